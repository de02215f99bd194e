//! A small element tree for reading and writing XML: well-formedness checked with positions,
//! attributes unescaped, bounded depth, and a writer with the project's layout (declaration,
//! two-space indentation). The typed FMI 3.0 model is converted to and from it, so every
//! error can name the element and the attribute it is about.

use quick_xml::events::{BytesStart, Event};
use quick_xml::{Reader, XmlVersion};

use crate::DescriptionError;

/// Deeper nesting than this is refused: no modelDescription nests beyond a few levels, and a
/// deliberately deep document would otherwise cost stack and time.
const MAX_DEPTH: usize = 64;

/// One XML element: its name, attributes in document order, child elements and its line.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Element {
    pub name: String,
    pub attributes: Vec<(String, String)>,
    pub children: Vec<Element>,
    /// 1-based line of the start tag (0 for elements built in memory).
    pub line: usize,
}

impl Element {
    /// An element with no attributes or children.
    pub fn new(name: &str) -> Element {
        Element { name: name.to_owned(), ..Default::default() }
    }

    /// The value of attribute `name`, if present.
    pub fn attribute(&self, name: &str) -> Option<&str> {
        self.attributes.iter().find(|(n, _)| n == name).map(|(_, v)| v.as_str())
    }

    /// Adds an attribute (builder style).
    pub fn with(mut self, name: &str, value: impl Into<String>) -> Element {
        self.attributes.push((name.to_owned(), value.into()));
        self
    }

    /// Adds an attribute when `value` is `Some`.
    pub fn with_opt(self, name: &str, value: Option<String>) -> Element {
        match value {
            Some(v) => self.with(name, v),
            None => self,
        }
    }

    /// The child elements called `name`, in document order.
    pub fn children_named<'a>(&'a self, name: &'a str) -> impl Iterator<Item = &'a Element> + 'a {
        self.children.iter().filter(move |c| c.name == name)
    }

    /// The first child element called `name`.
    pub fn child(&self, name: &str) -> Option<&Element> {
        self.children.iter().find(|c| c.name == name)
    }
}

/// 1-based line and column of a byte offset.
pub fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = &text.as_bytes()[..offset];
    let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
    let line_start = before.iter().rposition(|&b| b == b'\n').map_or(0, |p| p + 1);
    (line, offset - line_start + 1)
}

fn start_element(text: &str, offset: u64, e: &BytesStart) -> Result<Element, DescriptionError> {
    let name = e.name().0.to_owned();
    let (line, column) = line_column(text, offset as usize);
    let mut element = Element { name, line, ..Default::default() };
    for attribute in e.attributes() {
        let malformed = |what: String| {
            DescriptionError::new(format!("malformed XML at line {line}, column {column}: in the attributes of <{}>: {what}", element.name))
        };
        let attribute = attribute.map_err(|e| malformed(e.to_string()))?;
        let key = attribute.key.0.to_owned();
        let value = attribute.normalized_value(XmlVersion::Implicit1_0).map_err(|e| malformed(e.to_string()))?.into_owned();
        element.attributes.push((key, value));
    }
    Ok(element)
}

/// Parses `text` into its root element, refusing malformed XML with a line and column.
pub fn parse(text: &str) -> Result<Element, DescriptionError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let malformed = |offset: u64, what: &str| {
        let (line, column) = line_column(text, offset as usize);
        DescriptionError::new(format!("malformed XML at line {line}, column {column}: {what}"))
    };
    let mut reader = Reader::from_str(text);
    let mut open: Vec<Element> = Vec::new();
    let mut root: Option<Element> = None;
    loop {
        let offset = reader.buffer_position();
        let event = reader.read_event().map_err(|e| malformed(reader.error_position(), &e.to_string()))?;
        match event {
            Event::Start(ref e) | Event::Empty(ref e) => {
                let element = start_element(text, offset, e)?;
                if open.is_empty() && root.is_some() {
                    return Err(malformed(offset, &format!("second root element <{}>", element.name)));
                }
                if matches!(event, Event::Start(_)) {
                    if open.len() >= MAX_DEPTH {
                        return Err(malformed(offset, &format!("elements nested more than {MAX_DEPTH} deep")));
                    }
                    open.push(element);
                } else if let Some(parent) = open.last_mut() {
                    parent.children.push(element);
                } else {
                    root = Some(element);
                }
            }
            Event::End(_) => {
                let done = open.pop().expect("quick-xml checks that end tags match");
                match open.last_mut() {
                    Some(parent) => parent.children.push(done),
                    None => root = Some(done),
                }
            }
            Event::Text(ref t) if open.is_empty() && !t.trim().is_empty() => {
                return Err(malformed(offset, "text outside the root element"));
            }
            Event::Eof => break,
            _ => {}
        }
    }
    if let Some(unclosed) = open.last() {
        return Err(DescriptionError::new(format!(
            "malformed XML: the document ends before <{}> (opened at line {}) is closed",
            unclosed.name, unclosed.line
        )));
    }
    root.ok_or_else(|| DescriptionError::new("malformed XML: no root element found"))
}

fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\n' => out.push_str("&#10;"),
            '\r' => out.push_str("&#13;"),
            '\t' => out.push_str("&#9;"),
            c => out.push(c),
        }
    }
    out
}

fn write_element(element: &Element, depth: usize, out: &mut String) {
    let indent = "  ".repeat(depth);
    out.push_str(&indent);
    out.push('<');
    out.push_str(&element.name);
    for (name, value) in &element.attributes {
        out.push_str(&format!(" {name}=\"{}\"", escape(value)));
    }
    if element.children.is_empty() {
        out.push_str("/>\n");
        return;
    }
    out.push_str(">\n");
    for child in &element.children {
        write_element(child, depth + 1, out);
    }
    out.push_str(&format!("{indent}</{}>\n", element.name));
}

/// The document for `root`: UTF-8 declaration and two-space indentation.
pub fn write(root: &Element) -> String {
    let mut out = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    write_element(root, 0, &mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_nesting_attributes_and_positions() {
        let root = parse("<?xml version=\"1.0\"?>\n<a x=\"1 &amp; 2\">\n  <b/>\n  <c><d y=\"q\"/></c>\n</a>\n").unwrap();
        assert_eq!(root.name, "a");
        assert_eq!(root.attribute("x"), Some("1 & 2"));
        assert_eq!(root.children.iter().map(|c| c.name.as_str()).collect::<Vec<_>>(), ["b", "c"]);
        assert_eq!(root.child("c").unwrap().children[0].attribute("y"), Some("q"));
        assert_eq!(root.child("b").unwrap().line, 3);
    }

    #[test]
    fn refuses_malformed_documents_with_a_position() {
        assert!(parse("<a><b></a>").unwrap_err().message().contains("malformed XML at line 1"));
        assert!(parse("<a/><b/>").unwrap_err().message().contains("second root element <b>"));
        assert!(parse("<a>").unwrap_err().message().contains("ends before <a>"));
        assert!(parse("<a x=\"1\" x=\"2\"/>").unwrap_err().message().contains("in the attributes of <a>"));
        let deep = format!("{}{}", "<e>".repeat(100), "</e>".repeat(100));
        assert!(parse(&deep).unwrap_err().message().contains("nested more than 64 deep"));
        assert!(parse("").unwrap_err().message().contains("no root element"));
    }

    #[test]
    fn writing_then_reading_gives_the_same_tree() {
        let tree = Element::new("r").with("a", "x\"<&>\ny").with("b", "2");
        let tree = Element { children: vec![Element::new("c"), Element::new("d").with("e", "")], ..tree };
        let text = write(&tree);
        assert!(text.starts_with("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<r a="), "{text}");
        let mut back = parse(&text).unwrap();
        fn clear(e: &mut Element) {
            e.line = 0;
            e.children.iter_mut().for_each(clear);
        }
        clear(&mut back);
        assert_eq!(back, tree);
    }
}
