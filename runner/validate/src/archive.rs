//! Static checks of the `.fmu` archive, whatever its FMI version: a zip the standard allows
//! (stored or deflated entries, no links, no encryption, '/' separators), no entry that would
//! land outside the FMU's directory, only the standard's top-level layout, and
//! `documentation/` pages whose links resolve inside the archive. Then the archive is
//! unpacked with the importer's own safe extraction.

use std::collections::BTreeSet;
use std::path::Path;

use crate::report::Finding;

/// Top-level entries the standard defines (FMI 2.0.4 section 2.3, FMI 3.0 section 2.5).
const LAYOUT: [&str; 8] =
    ["modelDescription.xml", "model.png", "documentation", "sources", "binaries", "resources", "extra", "terminalsAndIcons"];

/// What the archive checks leave for the description checks.
pub(crate) struct Archive {
    /// modelDescription.xml as text, when present and readable.
    pub xml: Option<String>,
}

/// Checks the archive at `fmu` and extracts it into `dest`; `None` when it cannot be used.
pub(crate) fn check_and_extract(fmu: &Path, dest: &Path, findings: &mut Vec<Finding>) -> Option<Archive> {
    let file = match std::fs::File::open(fmu) {
        Ok(f) => f,
        Err(e) => {
            findings.push(Finding::error("archive.zip", format!("cannot open the FMU: {e}")));
            return None;
        }
    };
    let mut zip = match zip::ZipArchive::new(file) {
        Ok(z) => z,
        Err(e) => {
            findings.push(Finding::error("archive.zip", format!("the file is not a zip archive, as an FMU must be: {e}")));
            return None;
        }
    };
    let (mut zip_ok, mut paths_ok, mut layout_ok) = (true, true, true);
    let mut names = BTreeSet::new();
    let mut extra_top = BTreeSet::new();
    for i in 0..zip.len() {
        let entry = match zip.by_index_raw(i) {
            Ok(e) => e,
            Err(e) => {
                findings.push(Finding::error("archive.zip", format!("entry {i} cannot be read: {e}")));
                return None;
            }
        };
        let raw = String::from_utf8_lossy(entry.name_raw()).into_owned();
        let name = fmi_schema::escaped_and_cut(&raw, 200, "...");
        if let Some(why) = fmi_importer::archive::unsafe_entry_name(&raw) {
            paths_ok = false;
            findings.push(
                Finding::error("archive.paths", format!("entry '{name}' has {why}: unpacked, it would land outside the FMU's directory"))
                    .value(name.clone()),
            );
        }
        if raw.contains('\\') {
            zip_ok = false;
            findings.push(
                Finding::error("archive.zip", format!("entry '{name}' uses '\\' as a path separator, which zip forbids (only '/')"))
                    .value(name.clone()),
            );
        }
        if entry.is_symlink() {
            zip_ok = false;
            findings
                .push(Finding::error("archive.zip", format!("entry '{name}' is a symbolic link; the standard forbids links in an FMU")));
        }
        if entry.encrypted() {
            zip_ok = false;
            findings.push(Finding::error("archive.zip", format!("entry '{name}' is encrypted; the standard forbids encryption")));
        }
        let method = entry.compression();
        if !matches!(method, zip::CompressionMethod::Stored | zip::CompressionMethod::Deflated) {
            zip_ok = false;
            findings.push(Finding::error(
                "archive.zip",
                format!("entry '{name}' is compressed with {method:?}; the standard allows only store (0) and deflate (8)"),
            ));
        }
        let clean: Vec<&str> = raw.split(['/', '\\']).filter(|c| !c.is_empty() && *c != ".").collect();
        if let Some(top) = clean.first() {
            if !LAYOUT.contains(top) {
                extra_top.insert(fmi_schema::escaped_and_cut(top, 100, "..."));
            }
            for n in 1..=clean.len() {
                names.insert(clean[..n].join("/"));
            }
        }
    }
    for top in &extra_top {
        layout_ok = false;
        findings.push(
            Finding::warning("archive.layout", format!("'{top}' at the top of the archive is not part of the standard's layout"))
                .value(top.clone()),
        );
    }
    if !names.contains("modelDescription.xml") {
        findings.push(Finding::error("archive.layout", "the archive has no modelDescription.xml at its top level"));
        return None;
    }
    if zip_ok {
        findings.push(Finding::passed(
            "archive.zip",
            format!("a zip archive of {} entries, each stored or deflated, no links, no encryption", zip.len()),
        ));
    }
    if !paths_ok {
        findings.push(Finding::skipped("archive.documentation", "the archive was not unpacked: it has entries that escape its directory"));
        return None;
    }
    findings.push(Finding::passed("archive.paths", "no entry would land outside the FMU's directory"));
    if layout_ok {
        let tops: BTreeSet<&str> = names.iter().map(|n| n.split('/').next().unwrap_or("")).collect();
        findings.push(Finding::passed(
            "archive.layout",
            format!("only the standard's entries: {}", tops.into_iter().collect::<Vec<_>>().join(", ")),
        ));
    }
    drop(zip);
    let unpacked = fmi_importer::archive::check_zip(fmu, fmi_importer::archive::Limits::FMU).and_then(|checked| {
        // Copies of one entry with the same bytes unpack as one file (issue 33), but a tool
        // that refuses repeated names refuses the FMU.
        if !checked.duplicates().is_empty() {
            findings.push(Finding::warning(
                "archive.zip",
                format!(
                    "the archive lists {} more than once with the same bytes: unpacked once, but some tools refuse repeated entries",
                    checked.duplicates().iter().map(|d| format!("'{d}'")).collect::<Vec<_>>().join(", ")
                ),
            ));
        }
        checked.extract(dest)
    });
    if let Err(e) = unpacked {
        findings.push(Finding::error("archive.zip", format!("the archive cannot be unpacked safely: {e}")));
        return None;
    }
    check_documentation(dest, &names, findings);
    let xml = match std::fs::read(dest.join("modelDescription.xml")) {
        Ok(bytes) => match String::from_utf8(bytes) {
            Ok(text) => Some(text),
            Err(_) => {
                findings.push(Finding::error("description.xml", "modelDescription.xml is not UTF-8 text"));
                None
            }
        },
        Err(e) => {
            findings.push(Finding::error("description.xml", format!("modelDescription.xml cannot be read: {e}")));
            None
        }
    };
    Some(Archive { xml })
}

/// The links of an HTML page: the values of its `href` and `src` attributes.
fn links(html: &str) -> Vec<String> {
    let lower = html.to_ascii_lowercase();
    let bytes = html.as_bytes();
    let mut found = Vec::new();
    for attribute in ["href", "src"] {
        let mut from = 0;
        while let Some(at) = lower[from..].find(attribute).map(|i| i + from) {
            from = at + attribute.len();
            // A whole attribute name: preceded by whitespace, followed by optional spaces and '='.
            if at == 0 || !bytes[at - 1].is_ascii_whitespace() {
                continue;
            }
            let rest = &html[from..];
            let trimmed = rest.trim_start();
            let Some(after_equals) = trimmed.strip_prefix('=') else { continue };
            let value = after_equals.trim_start();
            let link = match value.chars().next() {
                Some(q @ ('"' | '\'')) => value[1..].split(q).next().unwrap_or(""),
                Some(_) => value.split(|c: char| c.is_ascii_whitespace() || c == '>').next().unwrap_or(""),
                None => "",
            };
            found.push(link.to_owned());
        }
    }
    found
}

/// `%XX` escapes decoded (a link to "my%20page.html" names "my page.html").
fn percent_decoded(text: &str) -> String {
    let bytes = text.as_bytes();
    let hex = |b: u8| (b as char).to_digit(16);
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' && i + 3 <= bytes.len() {
            if let (Some(high), Some(low)) = (hex(bytes[i + 1]), hex(bytes[i + 2])) {
                out.push((high * 16 + low) as u8);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Where a link in the page `page` (a path inside the archive) points, inside the archive:
/// `Ok(None)` for links outside it (web addresses, fragments of the same page), `Err` for a
/// link that cannot resolve inside it.
fn resolve(page: &str, link: &str) -> Result<Option<String>, &'static str> {
    let link = link.trim();
    let has_scheme = link.find(':').is_some_and(|i| {
        let scheme = &link[..i];
        !scheme.is_empty()
            && scheme.chars().next().is_some_and(|c| c.is_ascii_alphabetic())
            && scheme.chars().all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c))
    });
    if link.is_empty() || link.starts_with('#') || link.starts_with("//") || has_scheme {
        return Ok(None);
    }
    let path = link.split(['#', '?']).next().unwrap_or("");
    if path.is_empty() {
        return Ok(None);
    }
    if path.starts_with('/') {
        return Err("an absolute path, which has no meaning inside an FMU");
    }
    let mut parts: Vec<String> = page.split('/').map(str::to_owned).collect();
    parts.pop();
    for component in percent_decoded(path).split('/') {
        match component {
            "" | "." => {}
            ".." => {
                if parts.pop().is_none() {
                    return Err("a path that leaves the FMU");
                }
            }
            other => parts.push(other.to_owned()),
        }
    }
    Ok(Some(parts.join("/")))
}

fn check_documentation(dir: &Path, names: &BTreeSet<String>, findings: &mut Vec<Finding>) {
    if !names.contains("documentation") {
        findings.push(Finding::skipped("archive.documentation", "the FMU has no documentation/ directory"));
        return;
    }
    let mut fine = true;
    if !names.contains("documentation/index.html") {
        fine = false;
        findings.push(Finding::warning("archive.documentation", "documentation/ has no index.html, the entry point the standard names"));
    }
    let pages: Vec<&String> =
        names.iter().filter(|n| n.starts_with("documentation/") && (n.ends_with(".html") || n.ends_with(".htm"))).collect();
    let mut checked = 0;
    for page in &pages {
        let Ok(bytes) = std::fs::read(dir.join(page.as_str())) else { continue };
        let html = String::from_utf8_lossy(&bytes);
        for link in links(&html) {
            checked += 1;
            let shown = fmi_schema::escaped_and_cut(&link, 200, "...");
            match resolve(page, &link) {
                Ok(None) => {}
                Ok(Some(target)) if names.contains(&target) => {}
                Ok(Some(target)) => {
                    fine = false;
                    findings.push(
                        Finding::error(
                            "archive.documentation",
                            format!(
                                "{page} links to '{shown}', but the archive has no {}",
                                fmi_schema::escaped_and_cut(&target, 200, "...")
                            ),
                        )
                        .value(shown),
                    );
                }
                Err(why) => {
                    fine = false;
                    findings.push(Finding::error("archive.documentation", format!("{page} links to '{shown}', {why}")).value(shown));
                }
            }
        }
    }
    if fine {
        findings.push(Finding::passed(
            "archive.documentation",
            format!("{} page(s) in documentation/, {checked} link(s), every link inside the FMU resolves", pages.len()),
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn links_are_found_in_attributes_only() {
        let html = r#"<a href="a.html">x</a> <img SRC='img/b.png'> <a href = c.html>c</a> <p>href="not a link"</p> <a data-href="d">"#;
        assert_eq!(links(html), ["a.html", "c.html", "img/b.png"]);
    }

    #[test]
    fn links_resolve_relative_to_their_page() {
        let page = "documentation/index.html";
        assert_eq!(resolve(page, "derivation.html#eq1"), Ok(Some("documentation/derivation.html".into())));
        assert_eq!(resolve(page, "../resources/data.csv"), Ok(Some("resources/data.csv".into())));
        assert_eq!(resolve(page, "licenses/license%20text.txt"), Ok(Some("documentation/licenses/license text.txt".into())));
        assert_eq!(resolve(page, "https://fmi-standard.org/"), Ok(None));
        assert_eq!(resolve(page, "mailto:a@b.c"), Ok(None));
        assert_eq!(resolve(page, "#top"), Ok(None));
        assert_eq!(resolve(page, "//cdn.example/x.js"), Ok(None));
        assert!(resolve(page, "/etc/passwd").is_err());
        assert!(resolve(page, "../../../x").is_err());
        assert_eq!(percent_decoded("a%2Fb%zz%4"), "a/b%zz%4");
    }
}
