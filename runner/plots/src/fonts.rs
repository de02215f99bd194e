//! The font every figure is laid out and drawn with: DejaVu Sans, embedded (the `dejavu` crate),
//! so figures look the same on any machine and need no system fonts. plotters measures text
//! with it while laying a figure out; resvg shapes and draws the SVG's text with the same faces.

use std::sync::{Arc, Once, OnceLock};

use plotters::style::FontStyle;
use resvg::usvg::fontdb;

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

/// The faces resvg may use: DejaVu Sans regular and bold, standing for every generic family
/// (the SVG asks for "sans-serif"), and nothing from the system.
pub fn database() -> Arc<fontdb::Database> {
    static DATABASE: OnceLock<Arc<fontdb::Database>> = OnceLock::new();
    DATABASE
        .get_or_init(|| {
            let mut db = fontdb::Database::new();
            db.load_font_data(dejavu::sans::regular().to_vec());
            db.load_font_data(dejavu::sans::bold().to_vec());
            let family = "DejaVu Sans";
            db.set_sans_serif_family(family);
            db.set_serif_family(family);
            db.set_monospace_family(family);
            db.set_cursive_family(family);
            db.set_fantasy_family(family);
            Arc::new(db)
        })
        .clone()
}
