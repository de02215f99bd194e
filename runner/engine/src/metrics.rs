//! Sweep metrics: `NAME=EXPR` over per-run summaries of variables (`max(z_s)/max(z_r)`),
//! accumulated sample by sample. Their grammar, parser and streaming statistics are the
//! formulas crate's, which the models' tests and `runner handbook` read closed forms with too.

pub use formulas::metrics::{Accumulator, Expr, Metrics, Source, Stat};
