//! The font every plot is laid out and drawn with: DejaVu Sans, embedded in the runner (the
//! `dejavu` crate), so plots look the same on any machine and need no system fonts.

use std::sync::Once;

use plotters::style::FontStyle;

/// Registers DejaVu Sans as plotters' "sans-serif" (regular and bold); cheap after the first call.
pub fn register() {
    static REGISTERED: Once = Once::new();
    REGISTERED.call_once(|| {
        // The bytes are a font file compiled into the binary; failing to parse it is a build bug.
        for (style, bytes) in [(FontStyle::Normal, dejavu::sans::regular()), (FontStyle::Bold, dejavu::sans::bold())] {
            if plotters::style::register_font("sans-serif", style, bytes).is_err() {
                panic!("the embedded DejaVu Sans font does not parse");
            }
        }
    });
}
