//! A small element tree over quick-xml (SSP files, and the LS-REF manifests `runner simulate
//! --reference-file` reads): SSP files are small, and walking a tree keeps the
//! reader's rules (which child, which attribute) next to each other. Names are local names: the
//! prefixes (`ssd:`, `ssc:`, `ssv:`, `ssm:`) differ between tools, the local names do not.

use quick_xml::events::{BytesStart, Event};

/// An element: its local name, attributes and child elements (text is not needed by SSP).
#[derive(Debug, Clone, Default)]
pub struct Element {
    pub name: String,
    pub attributes: Vec<(String, String)>,
    pub children: Vec<Element>,
    /// The line the element starts on, for messages.
    pub line: usize,
}

impl Element {
    /// The attribute `name`, if present.
    pub fn attribute(&self, name: &str) -> Option<&str> {
        self.attributes.iter().find(|(n, _)| n == name).map(|(_, v)| v.as_str())
    }

    /// The attribute `name`, or an error naming the element and its line.
    pub fn required(&self, name: &str, file: &str) -> Result<&str, String> {
        self.attribute(name).ok_or_else(|| format!("{file}, line {}: <{}> has no attribute '{name}'", self.line, self.name))
    }

    /// The first child named `name`.
    pub fn child(&self, name: &str) -> Option<&Element> {
        self.children.iter().find(|c| c.name == name)
    }

    /// The children named `name`.
    pub fn children<'a>(&'a self, name: &'a str) -> impl Iterator<Item = &'a Element> + 'a {
        self.children.iter().filter(move |c| c.name == name)
    }

    /// The number in attribute `name`, if present; an error if it is not a number.
    pub fn number(&self, name: &str, file: &str) -> Result<Option<f64>, String> {
        match self.attribute(name) {
            None => Ok(None),
            Some(text) => {
                text.trim().parse::<f64>().ok().filter(|x| x.is_finite()).map(Some).ok_or_else(|| {
                    format!("{file}, line {}: <{} {name}=\"{text}\">: '{text}' is not a finite number", self.line, self.name)
                })
            }
        }
    }

    /// The boolean in attribute `name` (`true`/`false`/`1`/`0`), if present.
    pub fn flag(&self, name: &str, file: &str) -> Result<Option<bool>, String> {
        match self.attribute(name).map(str::trim) {
            None => Ok(None),
            Some("true" | "1") => Ok(Some(true)),
            Some("false" | "0") => Ok(Some(false)),
            Some(text) => Err(format!("{file}, line {}: <{} {name}=\"{text}\">: expected true or false", self.line, self.name)),
        }
    }
}

fn local(name: &str) -> String {
    match name.rsplit_once(':') {
        Some((_, local)) => local.to_owned(),
        None => name.to_owned(),
    }
}

/// Deeper nesting is refused: SSP files nest a few levels (systems in systems a few more), and
/// a deliberately deep file would otherwise cost memory and time.
const MAX_DEPTH: usize = 64;

fn start(e: &BytesStart, line: usize, file: &str) -> Result<Element, String> {
    let mut attributes = Vec::new();
    for a in e.attributes() {
        let a = a.map_err(|err| format!("{file}, line {line}: {err}"))?;
        let key: String = a.key.as_ref().to_owned();
        if key.starts_with("xmlns") {
            continue;
        }
        let value =
            a.normalized_value(quick_xml::XmlVersion::Implicit1_0).map_err(|err| format!("{file}, line {line}: {err}"))?.into_owned();
        attributes.push((local(&key), value));
    }
    Ok(Element { name: local(e.name().as_ref()), attributes, children: Vec::new(), line })
}

/// Parses `text` (the file `file`, for messages) into its root element.
pub fn parse(text: &str, file: &str) -> Result<Element, String> {
    let mut reader = quick_xml::Reader::from_str(text);
    let mut stack: Vec<Element> = Vec::new();
    let line_at = |pos: usize| text.as_bytes()[..pos.min(text.len())].iter().filter(|&&b| b == b'\n').count() + 1;
    loop {
        let pos = reader.buffer_position() as usize;
        let event = reader.read_event().map_err(|e| format!("{file}, line {}: not well-formed XML: {e}", line_at(pos)))?;
        match event {
            Event::Start(e) => {
                if stack.len() >= MAX_DEPTH {
                    return Err(format!("{file}, line {}: elements nest deeper than {MAX_DEPTH} levels", line_at(pos)));
                }
                stack.push(start(&e, line_at(pos), file)?)
            }
            Event::Empty(e) => {
                let element = start(&e, line_at(pos), file)?;
                match stack.last_mut() {
                    Some(parent) => parent.children.push(element),
                    None => return Ok(element),
                }
            }
            Event::End(_) => {
                let element = stack.pop().ok_or_else(|| format!("{file}: unbalanced end tag"))?;
                match stack.last_mut() {
                    Some(parent) => parent.children.push(element),
                    None => return Ok(element),
                }
            }
            Event::Eof => return Err(format!("{file}: no root element, or it is not closed")),
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prefixes_are_dropped_and_lines_kept() {
        let root = parse("<?xml version=\"1.0\"?>\n<a:Root xmlns:a=\"u\" x=\"1\">\n  <b:Child y=\"&lt;2\"/>\n</a:Root>", "f").unwrap();
        assert_eq!((root.name.as_str(), root.attribute("x"), root.line), ("Root", Some("1"), 2));
        let child = root.child("Child").unwrap();
        assert_eq!((child.attribute("y"), child.line), (Some("<2"), 3));
        assert!(parse("<a><b></a>", "f").unwrap_err().contains("not well-formed"));
        assert!(child.number("y", "f").unwrap_err().contains("'<2' is not a finite number"));
    }
}
