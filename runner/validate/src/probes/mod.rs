//! The dynamic checks, each a probe the probe process runs on one interface of a loaded
//! binary (see [`crate::probe`] for the framework): written once for both versions, over the
//! [`Instance`](crate::instance::Instance) calls and the version's state table.

mod arguments;
mod capabilities;
mod lifecycle;
mod state_machine;
mod strings;
mod values;

use crate::fmi::State;
use crate::probe::Ctx;

/// Runs probe `probe` (see [`crate::probe::known`]).
pub(crate) fn run(probe: &str, ctx: &mut Ctx) -> Result<(), String> {
    match probe {
        "lifecycle" => lifecycle::lifecycle(ctx),
        "reproducible" => lifecycle::reproducible(ctx)?,
        "arguments" => arguments::arguments(ctx),
        "strings" => strings::strings(ctx),
        "fmu-state" => capabilities::fmu_state(ctx, false),
        "serialize" => capabilities::fmu_state(ctx, true),
        "variable-step" => capabilities::variable_step(ctx),
        "threads" => capabilities::threads(ctx)?,
        other => {
            let state =
                other.strip_prefix("state-machine:").and_then(State::from_name).ok_or_else(|| format!("unknown probe {other:?}"))?;
            state_machine::state(ctx, state);
        }
    }
    Ok(())
}
