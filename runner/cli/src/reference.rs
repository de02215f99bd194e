//! `runner simulate --reference-file`: a run checked against reference results, pass or fail.
//!
//! The reference is a CSV in fmpy's and fmusim's layout (`time`, then one column per variable;
//! an array either as one column per element, `y[1]`, `y[2]`, ..., or as fmusim writes it, one
//! column whose cells list the elements separated by spaces), given as a file or, without one,
//! the result an FMU ships under the FMI-LS-REF layered standard
//! (`extra/org.fmi-standard.fmi-ls-ref/fmi-ls-manifest.xml`, its `<Related role="result">`).
//!
//! Every column the reference shares with the run is compared at every reference time with a
//! tube: |y − ref| ≤ rtol·|ref| + atol. The run's value at a reference time is its row at that
//! time (at an event, either of the rows there), else the linear interpolation of the rows
//! around it. The manifests of LS-REF 1.0.0-alpha.1 (the Reference FMUs') declare no tolerance,
//! so the tube is always the one of `--rtol` and `--atol`, by default rtol = 1e-3 and atol =
//! rtol · max|ref| of each column (a signal through zero keeps a band of its amplitude); the
//! verdict states it.

use std::io::Read;
use std::path::Path;

use runner_engine::input::same_time;

/// The layered standard's folder in an FMU.
pub const LS_REF_DIR: &str = "extra/org.fmi-standard.fmi-ls-ref";

/// The manifest's name in [`LS_REF_DIR`].
pub const MANIFEST: &str = "fmi-ls-manifest.xml";

/// The layered standard's version our manifests declare (the Reference FMUs' one).
const LS_REF_VERSION: &str = "1.0.0-alpha.1";

/// The default relative tolerance of the tube.
pub const DEFAULT_RTOL: f64 = 1e-3;

/// Largest reference CSV read from an FMU (an archive is untrusted: a size must not exhaust
/// memory).
const MAX_REFERENCE_BYTES: u64 = 256 << 20;

/// Largest manifest read.
const MAX_MANIFEST_BYTES: u64 = 1 << 20;

/// The tolerance tube: |y − ref| ≤ rtol·|ref| + atol, atol by default rtol·max|ref| per column.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tube {
    pub rtol: f64,
    /// Absolute tolerance for every column (`None`: rtol times each column's largest |ref|).
    pub atol: Option<f64>,
}

impl Tube {
    /// The tube of `--rtol` and `--atol`, with the defaults for those not given.
    pub fn new(rtol: Option<f64>, atol: Option<f64>) -> Result<Tube, String> {
        for (flag, value) in [("--rtol", rtol), ("--atol", atol)] {
            if let Some(x) = value.filter(|x| !(x.is_finite() && *x >= 0.0)) {
                return Err(format!("{flag} {x}: a tolerance is a finite number, 0 or more"));
            }
        }
        Ok(Tube { rtol: rtol.unwrap_or(DEFAULT_RTOL), atol })
    }

    /// The bound at a reference value `r` of a column whose largest |ref| is `amplitude`.
    fn bound(&self, r: f64, amplitude: f64) -> f64 {
        self.rtol * r.abs() + self.atol.unwrap_or(self.rtol * amplitude)
    }

    /// The tube in words.
    pub fn describe(&self) -> String {
        match self.atol {
            Some(atol) => format!("|y - ref| <= {:e}*|ref| + {:e}", self.rtol, atol),
            None => format!("|y - ref| <= {:e}*(|ref| + max|ref| of the column)", self.rtol),
        }
    }
}

/// A reference table: its name for messages, and its numeric columns.
#[derive(Debug, Clone)]
pub struct Reference {
    /// Where it comes from, for messages.
    pub label: String,
    /// The column names (without `time`), arrays expanded to `NAME[k]` (flat, 1-based).
    pub names: Vec<String>,
    /// The times, non-decreasing.
    pub time: Vec<f64>,
    /// One column per name; `None` where a cell is not a number (such a column is not compared).
    pub columns: Vec<Option<Vec<f64>>>,
    /// Per column: the array it is an element of, when a cell listed the elements.
    pub array_of: Vec<Option<String>>,
}

/// Reads the reference result `fmu` ships under LS-REF: the manifest's first `<Related>` of role
/// `result`. Returns its label and text; `None` when the FMU has no LS-REF manifest, an error
/// when the manifest is there but unusable (the Reference FMUs' Roberts.fmu names
/// BouncingBall's file, which it does not hold).
pub fn shipped(fmu: &Path) -> Result<Option<(String, String)>, String> {
    let file = std::fs::File::open(fmu).map_err(|e| format!("cannot open {}: {e}", fmu.display()))?;
    let mut zip = zip::ZipArchive::new(file).map_err(|e| format!("{}: not a zip archive: {e}", fmu.display()))?;
    let manifest_name = format!("{LS_REF_DIR}/{MANIFEST}");
    let Some(manifest) = read_entry(&mut zip, &manifest_name, MAX_MANIFEST_BYTES)? else {
        return Ok(None);
    };
    let root = fmi_systems::xml::parse(&manifest, &manifest_name)?;
    if root.name != "fmiReferences" {
        return Err(format!("{manifest_name}: the root element is <{}>, not LS-REF's <fmiReferences>", root.name));
    }
    let related = root
        .children("Related")
        .find(|r| r.attribute("role") == Some("result"))
        .ok_or_else(|| format!("{manifest_name} names no result (<Related role=\"result\">)"))?;
    let source = related.required("source", &manifest_name)?;
    if source.contains("..") || source.starts_with('/') || source.contains('\\') {
        return Err(format!("{manifest_name}: the result's source '{source}' leaves {LS_REF_DIR}"));
    }
    let entry = format!("{LS_REF_DIR}/{source}");
    let text = read_entry(&mut zip, &entry, MAX_REFERENCE_BYTES)?
        .ok_or_else(|| format!("{manifest_name} names '{source}' as its result, but the FMU has no {entry}"))?;
    Ok(Some((format!("{entry} (the FMU's LS-REF result)"), text)))
}

/// [`shipped`], for a command told to check against it: an FMU without a manifest is an error.
pub fn shipped_required(fmu: &Path) -> Result<Reference, String> {
    match shipped(fmu)? {
        Some((label, text)) => Reference::parse(&text, &label),
        None => {
            Err(format!("{} ships no reference results ({LS_REF_DIR}/{MANIFEST} is missing): give --reference-file REF.csv", fmu.display()))
        }
    }
}

/// The manifest LS-REF reads from [`LS_REF_DIR`], naming the result file `source` of the
/// default experiment (`description` says how it was computed): the shape the Reference FMUs'
/// manifests have.
pub fn manifest(source: &str, description: &str) -> String {
    let escape = |text: &str| text.replace('&', "&amp;").replace('<', "&lt;").replace('"', "&quot;");
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<fmiReferences
    xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
    xmlns:fmi-ls="http://fmi-standard.org/fmi-ls-manifest"
    fmi-ls:fmi-ls-name="org.fmi-standard.fmi-ls-ref"
    fmi-ls:fmi-ls-version="{LS_REF_VERSION}">
    <Related type="text/csv" source="{}" role="result" description="{}"/>
</fmiReferences>
"#,
        escape(source),
        escape(description)
    )
}

/// The text of the archive's entry `name` (`None` when there is none), refused past `limit`.
fn read_entry(zip: &mut zip::ZipArchive<std::fs::File>, name: &str, limit: u64) -> Result<Option<String>, String> {
    let entry = match zip.by_name(name) {
        Ok(entry) => entry,
        Err(zip::result::ZipError::FileNotFound) => return Ok(None),
        Err(e) => return Err(format!("{name}: {e}")),
    };
    let mut bytes = Vec::new();
    entry.take(limit + 1).read_to_end(&mut bytes).map_err(|e| format!("{name}: {e}"))?;
    if bytes.len() as u64 > limit {
        return Err(format!("{name} is larger than {limit} bytes"));
    }
    String::from_utf8(bytes).map(Some).map_err(|_| format!("{name} is not UTF-8 text"))
}

impl Reference {
    /// Reads and parses the reference CSV at `path`.
    pub fn read(path: &Path) -> Result<Reference, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        Reference::parse(&text, &path.display().to_string())
    }

    /// Parses a reference CSV (`label` names it in messages).
    pub fn parse(text: &str, label: &str) -> Result<Reference, String> {
        let mut reader = csv::ReaderBuilder::new().has_headers(true).trim(csv::Trim::All).comment(Some(b'#')).from_reader(text.as_bytes());
        let header: Vec<String> =
            reader.headers().map_err(|e| format!("{label}: its header cannot be read: {e}"))?.iter().map(str::to_owned).collect();
        if header.first().map(String::as_str) != Some("time") {
            return Err(format!("{label}: the first column must be 'time'"));
        }
        let mut rows = Vec::new();
        for record in reader.records() {
            let record = record.map_err(|e| format!("{label}: {e}"))?;
            rows.push(record);
        }
        if rows.is_empty() {
            return Err(format!("{label} has a header but no rows"));
        }
        let number = |cell: &str| match cell {
            "true" => Some(1.0),
            "false" => Some(0.0),
            _ => cell.parse::<f64>().ok().filter(|x| x.is_finite()),
        };
        let mut time = Vec::with_capacity(rows.len());
        for (i, r) in rows.iter().enumerate() {
            let t = number(&r[0]).ok_or_else(|| format!("{label}, row {}: time '{}' is not a finite number", i + 1, &r[0]))?;
            if time.last().is_some_and(|&last| t < last) {
                return Err(format!("{label}, row {}: time {t} comes after {}", i + 1, time.last().unwrap()));
            }
            time.push(t);
        }
        let mut reference = Reference { label: label.to_owned(), names: Vec::new(), time, columns: Vec::new(), array_of: Vec::new() };
        for (k, name) in header.iter().enumerate().skip(1) {
            // An array's cells list numbers; a text with spaces is one value.
            let width = rows.iter().map(|r| r[k].split_whitespace().count()).max().unwrap_or(1);
            let listed = rows.iter().all(|r| r[k].split_whitespace().all(|x| number(x).is_some()));
            if width <= 1 || !listed {
                reference.names.push(name.clone());
                reference.columns.push(rows.iter().map(|r| number(&r[k])).collect());
                reference.array_of.push(None);
                continue;
            }
            // An array as fmusim writes it; a row with another count of elements makes the
            // column one that is not compared.
            let cells: Vec<Vec<&str>> = rows.iter().map(|r| r[k].split_whitespace().collect()).collect();
            for e in 0..width {
                let column: Option<Vec<f64>> = cells.iter().map(|c| if c.len() == width { number(c[e]) } else { None }).collect();
                reference.names.push(format!("{name}[{}]", e + 1));
                reference.columns.push(column);
                reference.array_of.push(Some(name.clone()));
            }
        }
        Ok(reference)
    }
}

/// What a passed check compared.
#[derive(Debug, Clone, PartialEq)]
pub struct Verdict {
    /// The columns compared (as the run names them).
    pub compared: Vec<String>,
    /// The reference's columns not compared, each with why.
    pub skipped: Vec<String>,
    /// The reference times compared at.
    pub times: usize,
}

/// A sample outside the tube: the first in time, then column order.
#[derive(Debug, Clone, PartialEq)]
pub struct Violation {
    /// The reference's column.
    pub column: String,
    pub time: f64,
    /// The reference's row (1-based, the header not counted).
    pub row: usize,
    /// The run's value there.
    pub value: f64,
    pub reference: f64,
    pub bound: f64,
    /// The whole sentence, naming the reference and the tube.
    pub message: String,
}

/// Why a check failed: the run and the reference cannot be compared, or a sample is outside
/// the tube.
#[derive(Debug, Clone, PartialEq)]
pub enum Mismatch {
    Incomparable(String),
    Outside(Violation),
}

impl std::fmt::Display for Mismatch {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        match self {
            Mismatch::Incomparable(message) => f.write_str(message),
            Mismatch::Outside(v) => f.write_str(&v.message),
        }
    }
}

/// Checks the run (`names` its columns without time; `rows` its samples, time first, and
/// `comparable[c]` false for a column whose numbers are not its values, such as a String's)
/// against `reference` with `tube`: the verdict, or the first violation (in time, then column
/// order) named by column, time, value and bound.
pub fn check(
    reference: &Reference,
    names: &[String],
    comparable: &[bool],
    rows: &[(f64, Vec<f64>)],
    tube: Tube,
) -> Result<Verdict, Mismatch> {
    let (first, last) = match (rows.first(), rows.last()) {
        (Some(f), Some(l)) => (f.0, l.0),
        _ => return Err(Mismatch::Incomparable("the run wrote no rows to compare with the reference".to_owned())),
    };
    let (r_first, r_last) = (reference.time[0], *reference.time.last().expect("rows"));
    if (r_first < first && !same_time(r_first, first)) || (r_last > last && !same_time(r_last, last)) {
        return Err(Mismatch::Incomparable(format!(
            "{} spans t = {r_first} to {r_last} s, the run {first} to {last} s: run over the reference's time span (--start-time, --stop-time)",
            reference.label
        )));
    }
    // Each reference column's run column.
    let mut pairs = Vec::new();
    let mut skipped = Vec::new();
    for (k, name) in reference.names.iter().enumerate() {
        let ours = names.iter().position(|n| n == name).or_else(|| {
            // An n-dimensional array's flat element k is the run's k-th column of that array.
            let base = reference.array_of[k].as_ref()?;
            let flat: usize = name[base.len() + 1..name.len() - 1].parse().ok()?;
            let prefix = format!("{base}[");
            names.iter().enumerate().filter(|(_, n)| n.starts_with(&prefix)).nth(flat - 1).map(|(c, _)| c)
        });
        match (ours, &reference.columns[k]) {
            (None, _) => skipped.push(format!("{name} (not in the run)")),
            (Some(_), None) => skipped.push(format!("{name} (not numbers)")),
            (Some(c), Some(_)) if !comparable[c] => skipped.push(format!("{name} (the run's values are text)")),
            (Some(c), Some(values)) => {
                let amplitude = values.iter().fold(0.0f64, |m, x| m.max(x.abs()));
                pairs.push((k, c, values, amplitude));
            }
        }
    }
    if pairs.is_empty() {
        return Err(Mismatch::Incomparable(format!(
            "{} shares no column with the run (its columns: {}); choose the run's with --output-variable",
            reference.label,
            reference.names.join(", ")
        )));
    }
    let times: Vec<f64> = rows.iter().map(|r| r.0).collect();
    for (i, &t) in reference.time.iter().enumerate() {
        // The run's candidates at t: its rows at t, else the interpolation around t.
        let at = times.partition_point(|&x| x < t && !same_time(x, t));
        let same: Vec<usize> = (at..times.len()).take_while(|&j| same_time(times[j], t)).collect();
        for &(k, c, values, amplitude) in &pairs {
            let r = values[i];
            let bound = tube.bound(r, amplitude);
            let candidates: Vec<f64> = match same.is_empty() {
                false => same.iter().map(|&j| rows[j].1[c]).collect(),
                true => {
                    let (j0, j1) = (at - 1, at);
                    let (t0, t1, y0, y1) = (times[j0], times[j1], rows[j0].1[c], rows[j1].1[c]);
                    vec![y0 + (y1 - y0) * (t - t0) / (t1 - t0)]
                }
            };
            let closest = candidates.iter().copied().min_by(|a, b| (a - r).abs().total_cmp(&(b - r).abs())).expect("a candidate");
            // A NaN in the run (a failed value) is outside every tube.
            let inside = (closest - r).abs() <= bound;
            if !inside {
                let message = format!(
                    "{}: {} at t = {t} s (row {} of the reference): the run has {closest}, the reference {r}; |y - ref| = {:e} is above the bound {bound:e} ({})",
                    reference.label,
                    reference.names[k],
                    i + 1,
                    (closest - r).abs(),
                    tube.describe()
                );
                let column = reference.names[k].clone();
                return Err(Mismatch::Outside(Violation { column, time: t, row: i + 1, value: closest, reference: r, bound, message }));
            }
        }
    }
    Ok(Verdict { compared: pairs.iter().map(|&(k, ..)| reference.names[k].clone()).collect(), skipped, times: reference.time.len() })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(rows: &[(f64, f64)]) -> Vec<(f64, Vec<f64>)> {
        rows.iter().map(|&(t, y)| (t, vec![y])).collect()
    }

    /// Interpolation between the run's rows, either row at an event, and the first violation
    /// named by column, time, value and bound.
    #[test]
    fn the_tube_is_checked_at_every_reference_time() {
        let names = ["y".to_owned()];
        let ours = run(&[(0.0, 0.0), (1.0, 1.0), (1.0, 5.0), (2.0, 5.0)]);
        let tube = Tube::new(Some(0.0), Some(1e-12)).unwrap();
        let reference = Reference::parse("time,y\n0,0\n0.5,0.5\n1,1\n1,5\n2,5\n", "ref.csv").unwrap();
        let verdict = check(&reference, &names, &[true], &ours, tube).unwrap();
        assert_eq!((verdict.compared, verdict.times), (vec!["y".to_owned()], 5));
        let broken = Reference::parse("time,y\n0,0\n0.5,0.5\n1,1\n1.5,5.1\n2,5\n", "ref.csv").unwrap();
        let Err(Mismatch::Outside(violation)) = check(&broken, &names, &[true], &ours, tube) else { panic!("a violation") };
        let v = &violation;
        assert_eq!((v.column.as_str(), v.time, v.row, v.value, v.reference, v.bound), ("y", 1.5, 4, 5.0, 5.1, 1e-12));
        let err = violation.message;
        assert!(err.contains("y at t = 1.5 s (row 4 of the reference): the run has 5, the reference 5.1"), "{err}");
        let longer = Reference::parse("time,y\n0,0\n3,5\n", "ref.csv").unwrap();
        assert!(check(&longer, &names, &[true], &ours, tube).unwrap_err().to_string().contains("spans t = 0 to 3 s, the run 0 to 2 s"));
    }

    /// Arrays as fmusim writes them are compared element by element; the default atol follows
    /// each column's amplitude; a text column is not compared.
    #[test]
    fn arrays_and_the_default_tube() {
        let reference = Reference::parse("time,y,s\n0,1 2000,a b\n1,2 4000,b\n", "ref.csv").unwrap();
        assert_eq!(reference.names, ["y[1]", "y[2]", "s"]);
        let names = ["y[1]".to_owned(), "y[2]".to_owned(), "s".to_owned()];
        let rows = vec![(0.0, vec![1.0015, 2003.0, 0.0]), (1.0, vec![2.0, 4000.0, 0.0])];
        let tube = Tube::new(None, None).unwrap();
        // y[1]: bound 1e-3·1 + 1e-3·2 = 0.003 > 0.0015; y[2]: 2 + 4 = 6 > 3.
        let verdict = check(&reference, &names, &[true, true, false], &rows, tube).unwrap();
        assert_eq!(verdict.compared, ["y[1]", "y[2]"]);
        assert_eq!(verdict.skipped, ["s (not numbers)"]);
        let tight = Tube::new(Some(1e-3), Some(0.0)).unwrap();
        let err = check(&reference, &names, &[true, true, false], &rows, tight).unwrap_err().to_string();
        assert!(err.contains("y[1] at t = 0 s"), "{err}");
        assert!(Tube::new(Some(-1.0), None).unwrap_err().contains("--rtol -1"));
    }
}
