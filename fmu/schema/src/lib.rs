//! modelDescription.xml of FMI 2.0 ([`fmi2`]) and FMI 3.0 (`fmi3`, beside it), and FMI 1.0's read
//! only ([`fmi1`]): typed models,
//! XML reading and writing, and `check()`, the self-check of a description against the
//! standard's rules. The importer reads any tool's descriptions with it; the export toolkit
//! writes ours with it.

use std::fmt;

/// Error from reading or writing a model description; the message says what and where.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DescriptionError {
    message: String,
}

impl DescriptionError {
    /// Creates an error carrying a human-readable message, made [`printable`] (messages quote
    /// text from the file, which may be hostile).
    pub fn new(message: impl Into<String>) -> Self {
        DescriptionError { message: printable(message.into()) }
    }

    /// The human-readable message (what is wrong and where).
    pub fn message(&self) -> &str {
        &self.message
    }
}

/// `message` fit for a terminal and a log: control characters (an escape sequence, a newline
/// in an attribute) are written as escapes, and a message is cut at 1,000 characters, because
/// it may quote a megabyte-long attribute value.
pub fn printable(message: String) -> String {
    const MAX_MESSAGE_CHARS: usize = 1000;
    if message.len() <= MAX_MESSAGE_CHARS && !message.chars().any(char::is_control) {
        return message;
    }
    escaped_and_cut(&message, MAX_MESSAGE_CHARS, "... (cut)")
}

/// `text` from a file someone else wrote, as a message may quote it: control characters (terminal
/// escapes, NUL, newlines) written as escapes, and cut after `max_chars` characters, `cut_mark`
/// showing where.
pub fn escaped_and_cut(text: &str, max_chars: usize, cut_mark: &str) -> String {
    let mut out = String::with_capacity(text.len().min(max_chars) + cut_mark.len());
    for c in text.chars().take(max_chars) {
        if c.is_control() {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    if text.chars().nth(max_chars).is_some() {
        out.push_str(cut_mark);
    }
    out
}

impl fmt::Display for DescriptionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for DescriptionError {}

/// Declares a fieldless enum whose variants map one-to-one onto FMI attribute strings.
macro_rules! fmi_enum {
    (
        $(#[$meta:meta])*
        $name:ident, $what:literal { $($(#[$vmeta:meta])* $variant:ident = $text:literal),+ $(,)? }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        pub enum $name {
            $($(#[$vmeta])* $variant),+
        }

        impl $name {
            /// All values, in the order the standard lists them.
            pub const ALL: &'static [$name] = &[$($name::$variant),+];

            /// The attribute value as written in modelDescription.xml.
            pub fn as_str(self) -> &'static str {
                match self {
                    $($name::$variant => $text),+
                }
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str(self.as_str())
            }
        }

        impl FromStr for $name {
            type Err = String;

            fn from_str(s: &str) -> Result<Self, String> {
                match s.trim() {
                    $($text => Ok($name::$variant),)+
                    other => Err(format!(
                        "'{}' is not a valid {} (expected one of: {})",
                        other,
                        $what,
                        [$($text),+].join(", ")
                    )),
                }
            }
        }
    };
}

/// Shortest text that parses back to the same f64 (Rust's float formatting is shortest
/// round-trip); exponent form for tiny/huge values keeps 1e-9 or 1e308 short, and the XML
/// Schema spellings are used for the non-finite values.
pub(crate) fn format_real(value: f64) -> String {
    if value.is_nan() {
        return "NaN".to_string();
    }
    if value.is_infinite() {
        return if value > 0.0 { "INF" } else { "-INF" }.to_string();
    }
    let text = format!("{value:?}");
    match text.strip_suffix(".0") {
        Some(integral) => integral.to_string(),
        None => text,
    }
}

/// The `fmiVersion` attribute of a modelDescription.xml's root element, read without parsing
/// the rest, to choose the schema to read it with.
pub fn fmi_version(xml: &str) -> Result<String, DescriptionError> {
    use quick_xml::events::Event;
    let text = xml.strip_prefix('\u{feff}').unwrap_or(xml);
    let mut reader = quick_xml::Reader::from_str(text);
    loop {
        match reader.read_event() {
            Ok(Event::Start(e) | Event::Empty(e)) => {
                let version = e
                    .try_get_attribute("fmiVersion")
                    .ok()
                    .flatten()
                    .and_then(|a| a.normalized_value(quick_xml::XmlVersion::Implicit1_0).ok().map(|v| v.trim().to_owned()));
                return version.ok_or_else(|| {
                    DescriptionError::new(format!(
                        "the root element <{}> has no fmiVersion attribute (not a modelDescription.xml)",
                        e.name().0
                    ))
                });
            }
            Ok(Event::Eof) => return Err(DescriptionError::new("malformed XML: no root element found")),
            Err(e) => return Err(DescriptionError::new(format!("malformed XML: {e}"))),
            Ok(_) => {}
        }
    }
}

pub mod fmi1;
pub mod fmi2;
pub mod fmi3;
mod tree;
