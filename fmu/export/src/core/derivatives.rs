//! Exact partial derivatives of an instance's equations: FMI's directional derivatives
//! (`fmi2GetDirectionalDerivative`, `fmi3GetDirectionalDerivative`) and adjoint derivatives
//! (`fmi3GetAdjointDerivative`), independent of the FMI version.
//!
//! The model's equations are generic over their number type ([`crate::Scalar`]). The instance
//! lifts its model into dual numbers ([`crate::Lift`]), gives each known its value and its
//! seed as derivative part, and runs the same initial state, right-hand side and outputs the
//! simulation runs: the derivative parts of the unknowns are then `J seed` to rounding
//! (forward-mode automatic differentiation), with `J` the Jacobian of the equations of the
//! current regime. Nothing is differentiated numerically and nothing by hand.
//!
//! Which variables are unknowns and knowns follows the standard (FMI 2.0 section 2.1.9 and the
//! ModelStructure's `dependencies`, FMI 3.0 section 2.2.11):
//! - Initialization Mode: the unknowns are the Real initial unknowns (outputs whose `initial`
//!   is not `exact`, the states among them; calculated parameters; state derivatives), the
//!   knowns the Real inputs, the Real variables with `initial="exact"` (the parameters) and
//!   the independent variable `time`.
//! - Continuous-Time Mode: the unknowns are the continuous Real outputs and the state
//!   derivatives; Event Mode adds the discrete Real outputs; a Co-Simulation communication
//!   point (Step Mode) has every Real output and the state derivatives. The knowns are the Real
//!   inputs, the continuous states and `time`.
//!
//! Anything else is refused with an error naming the variable and what the mode allows.
//! Solver controls are knowns where parameters are, with derivative 0: the equations do not
//! depend on them.

use nalgebra::SVector;
use num_dual::{Derivative, Dual2_64, Dual3_64, Dual64, DualSVec64};

use super::interpolation::MAX_ORDER;
use super::{CallResult, Core, Failure};
use crate::model::{Access, BaseType, Causality, Equations, Initial, Lift, Model, ModelError, Variability};
use crate::table::{Row, Slot};
use crate::taylor3::Taylor3;

/// The mode whose equations are differentiated (FMI 2.0 section 2.1.9).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Initialization Mode: the initial unknowns as functions of the parameters and inputs.
    Initialization,
    /// Model Exchange Continuous-Time Mode.
    ContinuousTime,
    /// Model Exchange Event Mode.
    Event,
    /// Co-Simulation at a communication point (Step Mode, and the states after a step).
    Step,
}

impl Mode {
    /// The mode as the standard names it, for messages.
    fn name(self) -> &'static str {
        match self {
            Mode::Initialization => "Initialization Mode",
            Mode::ContinuousTime => "Continuous-Time Mode",
            Mode::Event => "Event Mode",
            Mode::Step => "Step Mode",
        }
    }

    /// What the unknowns and knowns are in this mode, for messages.
    fn rule(self) -> &'static str {
        match self {
            Mode::Initialization => {
                "the unknowns are the Real initial unknowns (outputs and states not exact, calculated parameters, state derivatives), the knowns the Real inputs, exact parameters and time"
            }
            Mode::ContinuousTime => {
                "the unknowns are the continuous Real outputs and the state derivatives, the knowns the Real inputs, the continuous states and time"
            }
            Mode::Event | Mode::Step => {
                "the unknowns are the Real outputs and the state derivatives, the knowns the Real inputs, the continuous states and time"
            }
        }
    }
}

/// True when `row` is an unknown of `mode`'s equations.
pub fn is_unknown<M>(row: &Row<M>, mode: Mode) -> bool {
    if row.base_type != BaseType::Real {
        return false;
    }
    let derivative = matches!(row.slot, Slot::Derivative(_));
    match mode {
        // As the modelDescription's InitialUnknowns list them (an output's absent `initial`
        // is `calculated`).
        Mode::Initialization => {
            derivative
                || row.causality == Causality::CalculatedParameter
                || (row.causality == Causality::Output && row.initial != Some(Initial::Exact))
        }
        Mode::ContinuousTime => derivative || (row.causality == Causality::Output && row.variability == Variability::Continuous),
        Mode::Event | Mode::Step => derivative || row.causality == Causality::Output,
    }
}

/// True when `row` is a known of `mode`'s equations.
pub fn is_known<M>(row: &Row<M>, mode: Mode) -> bool {
    if row.base_type != BaseType::Real {
        return false;
    }
    match (&row.slot, mode) {
        (Slot::Time, _) => true,
        (_, _) if row.causality == Causality::Input => true,
        (Slot::Model(Access::State(_)), Mode::ContinuousTime | Mode::Event | Mode::Step) => true,
        (_, Mode::Initialization) => row.initial == Some(Initial::Exact) && row.causality == Causality::Parameter,
        _ => false,
    }
}

/// Dual numbers with this many derivative parts carry that many columns of a Jacobian
/// through one evaluation of the equations.
pub const LANES: usize = 8;

/// The Jacobian blocks an instance computed at its current point, which the directional and
/// adjoint derivatives read until the point changes. An importer asks for a Jacobian column by
/// column (one known seeded per call) or row by row: the first call at a point that needs a
/// block computes it, in vector-mode passes of [`LANES`] knowns each; the other calls only
/// multiply. A block is the rows of the state derivatives or of the other unknowns, in the
/// columns of the states or of the other knowns (time, inputs, parameters): an implicit
/// solver asks for the states' columns alone, which then take the narrowest numbers and leave
/// the inputs unseeded. The point is the mode, the time, the states and the instance's
/// `version`, which every set, event, reset or restored state moves on.
#[derive(Default)]
pub(crate) struct Jacobians {
    /// The mode the layout below is for.
    mode: Option<Mode>,
    /// The mode's known (the states first) and unknown rows, what a forward pass seeds and
    /// reads for each (the derivatives' rows and the others'), and each table row's place
    /// among them.
    knowns: Vec<usize>,
    /// The first this many columns are a block: the states' (or every known's, see
    /// [`Core::jacobian_layout`]).
    state_columns: usize,
    seeds: Vec<Known>,
    /// The places of the knowns that are model fields ([`field_places`]).
    fields: Vec<usize>,
    /// The columns of the states' block when it is an implicit solver's d(der x)/dx (the
    /// states in order, then at most the time, no field among them, one pass wide; else 0):
    /// such a block at a new point is [`states`]'s one pass, kept in `solver_block`.
    solver_columns: usize,
    unknowns: Vec<usize>,
    derivative_block: Vec<(usize, Unknown)>,
    other_block: Vec<(usize, Unknown)>,
    /// What a pass for each evaluates (found once: a scan per pass cost 140 instructions).
    derivative_evaluates: Evaluates,
    other_evaluates: Evaluates,
    /// Per unknown place: a state derivative.
    is_derivative: Vec<bool>,
    known_at: Vec<u32>,
    unknown_at: Vec<u32>,
    /// (version, bits of t) and the bits of x the values were computed at.
    point: Option<(u64, u64)>,
    x: Vec<u64>,
    /// Row-major: unknowns x knowns.
    values: Vec<f64>,
    /// Per known: an input's or parameter's value at the point, else 0.
    known_values: Vec<f64>,
    /// The instance's version `known_values` were read at, when no input was driven then
    /// ([`Core::new_jacobians_point`]); `None` when they are to be read at the next new point.
    fields_read_at: Option<u64>,
    /// The model lifted into the passes' dual numbers, kept while the version stays.
    lifted: KeptLift,
    /// Per row block (derivatives, others) and column block (states, others): computed at
    /// the point.
    done: [[bool; 2]; 2],
    /// The unknowns of the last call checked against this layout, their places and blocks: an
    /// importer asks for every column with the same unknowns, which are checked once.
    asked: Vec<u32>,
    asked_at: Vec<u32>,
    /// Where their rows start in `values` (`asked_at` times the knowns' count).
    asked_rows: Vec<usize>,
    asked_blocks: Blocks,
    /// The asked unknowns are the state derivatives, all and in order: the columns of
    /// `solver_block` are theirs.
    asked_derivatives: bool,
    /// d(der x)/d(known) for the first `solver_columns` knowns, column by column (`n` values
    /// each, in the derivatives' order), at the point, when `solver_block_current`: what an
    /// implicit solver's unit-seed calls read, computed by [`states`] in one pass without
    /// the general blocks' bookkeeping. Apart from `values` (its own `done` flags).
    solver_block: Vec<f64>,
    solver_block_current: bool,
}

/// The row blocks of [`Jacobians`] a call's unknowns are in (state derivatives, others), or
/// the column blocks its knowns are in (states, others).
type Blocks = [bool; 2];

/// Not a known or unknown of the mode.
const ABSENT: u32 = u32::MAX;

/// The value references `a` and `b` (of the same length) are the same: two at a time (one
/// 64-bit compare) and the odd one apart, without a branch per value (by fours: a loop more to
/// set up for a model of two states, mass_spring_damper +10 instructions per Jacobian).
#[inline(always)]
fn same_references(a: &[u32], b: &[u32]) -> bool {
    let ((a_pairs, a_odd), (b_pairs, b_odd)) = (a.as_chunks::<2>(), b.as_chunks::<2>());
    let pairs = a_pairs.iter().zip(b_pairs).fold(true, |same, (x, y)| same & (x == y));
    pairs & a_odd.iter().zip(b_odd).fold(true, |same, (x, y)| same & (x == y))
}

impl Jacobians {
    /// The place of row `vr` among the unknowns (`unknown`) or the knowns.
    #[inline]
    fn place(&self, vr: u32, unknown: bool) -> Option<usize> {
        let at = if unknown { &self.unknown_at } else { &self.known_at };
        at.get(vr as usize).copied().filter(|&p| p != ABSENT).map(|p| p as usize)
    }

    /// The last call's unknowns (`asked_at`) in the known at place `column`, times `seed`,
    /// into `sensitivity`: an importer asks for a Jacobian column by column, one known seeded.
    /// Whether the values are all finite.
    #[inline(always)]
    fn column_times(&self, column: usize, seed: f64, sensitivity: &mut [f64]) -> bool {
        // The column's values from the start: a slice in registers, not the Vec read again
        // after every store to `sensitivity` (which may alias it, for all the compiler knows).
        let values = self.values.get(column..).unwrap_or_default();
        // v * 0 is zero for a finite v and NaN otherwise: two instructions per value where
        // `is_finite` and the flag's update took five.
        let mut probe = 0.0;
        for (out, &row) in sensitivity.iter_mut().zip(&self.asked_rows) {
            // Adding to 0.0 as the general sum does keeps its results to the bit (-0.0 too).
            let mut v = 0.0;
            v += values[row] * seed;
            probe += v * 0.0;
            *out = v;
        }
        probe == 0.0
    }

    /// [`Jacobians::column_times`] from the implicit solver's block (the asked unknowns are
    /// the state derivatives in order, `n` of them: the model's constant count, so the loop
    /// unrolls): the same sums. False, for the general path, when the block has no such column.
    #[inline(always)]
    fn solver_column_times(&self, column: usize, seed: f64, sensitivity: &mut [f64], n: usize) -> bool {
        let Some(values) = self.solver_block.get(column * n..column * n + n) else { return false };
        let mut probe = 0.0;
        for (out, &value) in sensitivity[..n].iter_mut().zip(values) {
            let mut v = 0.0;
            v += value * seed;
            probe += v * 0.0;
            *out = v;
        }
        probe == 0.0
    }
}

impl<M: Model> Core<M> {
    /// The layout of `mode`'s knowns and unknowns (made when the mode changes).
    fn jacobian_layout(&mut self, mode: Mode) {
        let j = &mut self.jacobians;
        if j.mode == Some(mode) {
            return;
        }
        let rows = &self.table.rows;
        j.mode = Some(mode);
        j.point = None;
        j.solver_block_current = false;
        j.asked_derivatives = false;
        j.asked.clear();
        j.asked_at.clear();
        j.asked_rows.clear();
        j.asked_blocks = Blocks::default();
        j.knowns = (0..rows.len()).filter(|&i| is_known(&rows[i], mode)).collect();
        // The states first: their columns are a block of their own when the other knowns
        // include inputs or parameters, whose seeding costs the derived fields computed again
        // (measured: quarter_car 3587 -> 3311 instructions per Jacobian of the states'
        // columns). Else one block: time and states in one pass cost less than in two
        // (second_order 1256 against 1342).
        let is_state = |i: usize| matches!(rows[i].slot, Slot::Model(Access::State(_)));
        j.knowns.sort_by_key(|&i| !is_state(i));
        j.unknowns = (0..rows.len()).filter(|&i| is_unknown(&rows[i], mode)).collect();
        j.seeds = j
            .knowns
            .iter()
            .map(|&row| match (&rows[row].slot, rows[row].field) {
                (Slot::Time, _) => Known::Time,
                (Slot::Model(Access::State(k)), _) => Known::State(*k),
                (Slot::Model(Access::Real { .. }), Some(field)) => Known::Field(field),
                // Solver controls: the equations do not depend on them.
                _ => Known::Constant,
            })
            .collect();
        j.fields = field_places(&j.seeds);
        let states = j.knowns.iter().filter(|&&i| is_state(i)).count();
        let fields = j.seeds[states..].iter().any(|s| matches!(s, Known::Field(_)));
        j.state_columns = if fields { states } else { j.knowns.len() };
        let columns = &j.seeds[..j.state_columns];
        let solver = mode != Mode::Initialization
            && states == M::N_STATES
            && (1..=LANES).contains(&columns.len())
            && columns.iter().enumerate().all(|(l, k)| *k == if l < states { Known::State(l) } else { Known::Time });
        j.solver_columns = if solver { columns.len() } else { 0 };
        // Sized once per layout: a new point only overwrites what it computes.
        j.values.clear();
        j.values.resize(j.unknowns.len() * j.knowns.len(), 0.0);
        j.solver_block.clear();
        j.solver_block.resize(j.solver_columns * M::N_STATES, 0.0);
        j.x = vec![0; M::N_STATES];
        // Only the fields' values are read at a new point; the other knowns' stay 0.
        j.known_values = vec![0.0; j.knowns.len()];
        j.fields_read_at = None;
        j.is_derivative = j.unknowns.iter().map(|&row| matches!(rows[row].slot, Slot::Derivative(_))).collect();
        let target = |row: usize| match (&rows[row].slot, rows[row].field) {
            (Slot::Derivative(k), _) => Unknown::Derivative(*k),
            (Slot::Model(Access::State(k)), _) => Unknown::State(*k),
            (Slot::Model(Access::Real { .. }), Some(field)) => Unknown::Field(field),
            _ => Unknown::Zero,
        };
        let block = |derivatives: bool| -> Vec<(usize, Unknown)> {
            let rows = j.unknowns.iter().zip(&j.is_derivative).enumerate();
            rows.filter(|(_, (_, &d))| d == derivatives).map(|(place, (&row, _))| (place, target(row))).collect()
        };
        (j.derivative_block, j.other_block) = (block(true), block(false));
        (j.derivative_evaluates, j.other_evaluates) = (Evaluates::of(&j.derivative_block), Evaluates::of(&j.other_block));
        j.known_at = vec![ABSENT; rows.len()];
        j.unknown_at = vec![ABSENT; rows.len()];
        for (place, &row) in j.knowns.iter().enumerate() {
            j.known_at[row] = place as u32;
        }
        for (place, &row) in j.unknowns.iter().enumerate() {
            j.unknown_at[row] = place as u32;
        }
    }

    /// Checks the call's value references against `mode`'s layout: the refusal names the first
    /// that is not an unknown, or a known, of the mode. Says which blocks the unknowns are in;
    /// the unknowns are checked once while the calls ask for the same ones (their places then
    /// in `asked_at`).
    fn check_derivative_call(&mut self, unknowns: &[u32], knowns: &[u32], mode: Mode, function: &str) -> Result<Blocks, Failure> {
        self.jacobian_layout(mode);
        if self.jacobians.asked.as_slice() != unknowns {
            let j = &self.jacobians;
            let mut blocks = Blocks::default();
            for &vr in unknowns {
                match j.place(vr, true) {
                    Some(p) => blocks[usize::from(!j.is_derivative[p])] = true,
                    None => return Err(self.not_in_mode(vr, "an unknown", mode, function)),
                }
            }
            let j = &mut self.jacobians;
            let derivative = |(k, &vr): (usize, &u32)| {
                let place = j.unknown_at[vr as usize] as usize;
                j.derivative_block.iter().any(|&(p, u)| p == place && u == Unknown::Derivative(k))
            };
            j.asked_derivatives = unknowns.len() == self.state.x.len() && unknowns.iter().enumerate().all(derivative);
            j.asked.clear();
            j.asked.extend_from_slice(unknowns);
            j.asked_at.clear();
            j.asked_at.extend(unknowns.iter().map(|&vr| j.unknown_at[vr as usize]));
            j.asked_rows.clear();
            j.asked_rows.extend(j.asked_at.iter().map(|&place| place as usize * j.knowns.len()));
            j.asked_blocks = blocks;
        }
        let j = &self.jacobians;
        match knowns.iter().find(|&&vr| j.place(vr, false).is_none()) {
            None => Ok(j.asked_blocks),
            Some(&vr) => Err(self.not_in_mode(vr, "a known", mode, function)),
        }
    }

    /// The column blocks (states, others) of `knowns`, all checked to be knowns.
    fn column_blocks(&self, knowns: &[u32]) -> Blocks {
        let j = &self.jacobians;
        let mut blocks = Blocks::default();
        for &vr in knowns {
            blocks[usize::from(j.known_at[vr as usize] as usize >= j.state_columns)] = true;
        }
        blocks
    }

    #[cold]
    #[inline(never)]
    fn not_in_mode(&self, vr: u32, what: &str, mode: Mode, function: &str) -> Failure {
        match self.table.rows.get(vr as usize) {
            Some(row) => Failure::error(format!(
                "{function}: '{}' (value reference {vr}) is not {what} in {}: {}",
                row.name,
                mode.name(),
                mode.rule()
            )),
            None => Failure::error(format!("{function}: value reference {vr} is not a variable of this FMU")),
        }
    }

    /// `fmiGetDirectionalDerivative`: `sensitivity = J seed`, `J` the Jacobian of the
    /// `unknowns` with respect to the `knowns` in `mode` (see the module documentation).
    /// `function` names the caller in messages. Nothing the importer sees changes.
    pub fn directional_derivative(
        &mut self,
        unknowns: &[u32],
        knowns: &[u32],
        seed: &[f64],
        sensitivity: &mut [f64],
        mode: Mode,
        function: &str,
    ) -> CallResult {
        if seed.len() != knowns.len() || sensitivity.len() != unknowns.len() {
            return Err(Failure::error(format!(
                "{function}: {} seed values for {} knowns and room for {} sensitivities of {} unknowns: give one per known and one per unknown",
                seed.len(),
                knowns.len(),
                sensitivity.len(),
                unknowns.len()
            )));
        }
        let rows = self.check_derivative_call(unknowns, knowns, mode, function)?;
        self.jacobian_blocks(rows, self.column_blocks(knowns), mode)?;
        let j = &self.jacobians;
        let width = j.knowns.len();
        let mut finite = true;
        if let ([k], [s]) = (knowns, seed) {
            finite = j.column_times(j.known_at[*k as usize] as usize, *s, sensitivity);
        } else {
            for (out, &place) in sensitivity.iter_mut().zip(&j.asked_at) {
                let row = &j.values[place as usize * width..][..width];
                let mut sum = 0.0;
                for (&k, &s) in knowns.iter().zip(seed) {
                    sum += row[j.known_at[k as usize] as usize] * s;
                }
                finite &= sum.is_finite();
                *out = sum;
            }
        }
        if finite {
            Ok(())
        } else {
            Err(self.not_differentiable(sensitivity, unknowns, true, function))
        }
    }

    /// [`Core::directional_derivative`] when the full call's checks are known to pass: one
    /// known seeded, the unknowns of the last call (checked then), in the mode of the layout
    /// (not Initialization Mode, whose reads may compute the initial state). That is how an
    /// importer asks for a Jacobian, column by column; the first column of a block at a new
    /// point computes the block. `None` otherwise, nothing written (also when computing fails):
    /// the full call checks, computes and explains. Else whether the values are all finite.
    #[inline(always)]
    pub fn try_directional_derivative(
        &mut self,
        unknowns: &[u32],
        knowns: &[u32],
        seed: &[f64],
        sensitivity: &mut [f64],
        mode: Mode,
    ) -> Option<bool> {
        let j = &self.jacobians;
        let ([k], [s]) = (knowns, seed) else { return None };
        // The known's place, `ABSENT` (above every column count) when it is none: the solver's
        // column test below rules that out without a test of its own.
        let column = *j.known_at.get(*k as usize)? as usize;
        // The implicit solver's column first, its request compared over the model's constant
        // count of states (unrolled: mass_spring_damper's two unknowns one 64-bit compare).
        // Anything else, or a request that differs, takes the general checks below.
        let n = M::N_STATES;
        if j.asked_derivatives
            && column < j.solver_columns
            && j.mode == Some(mode)
            && mode != Mode::Initialization
            && unknowns.len() == n
            && sensitivity.len() == n
            && j.asked.len() == n
            && same_references(&j.asked[..n], &unknowns[..n])
        {
            let at_point = self.at_jacobians_point();
            if !(j.solver_block_current && at_point) {
                self.solver_block(at_point).ok()?;
            }
            return Some(self.jacobians.solver_column_times(column, *s, sensitivity, n));
        }
        let column = j.place(*k, false)?;
        let checked = j.mode == Some(mode)
            && mode != Mode::Initialization
            && sensitivity.len() == unknowns.len()
            && j.asked.len() == unknowns.len()
            // Compared in line, without a branch per value: the few unknowns of a small model
            // cost less than bcmp's call (18 instructions a column for two); two at a time.
            && same_references(&j.asked, unknowns);
        if !checked {
            return None;
        }
        // (The implicit solver's columns were answered above: `asked_derivatives` means as many
        // unknowns as the model's constant count of states.)
        let at_point = self.at_jacobians_point();
        let group = usize::from(column >= j.state_columns);
        let rows = j.asked_blocks;
        let blocks_done = (j.done[0][group] || !rows[0]) && (j.done[1][group] || !rows[1]);
        if !(blocks_done && at_point) {
            // The first column of its block at a new point: the call is the last one's but
            // for its known, so only the blocks are made. A failure goes to the general path
            // to be explained.
            let mut columns = Blocks::default();
            columns[group] = true;
            self.jacobian_blocks(rows, columns, mode).ok()?;
        }
        Some(self.jacobians.column_times(column, *s, sensitivity))
    }

    /// The implicit solver's block ([`Jacobians::solver_block`]) at the current point,
    /// `at_point` when the point is the general blocks' already: one pass of [`states`], the
    /// same numbers and arithmetic as [`Core::jacobian_blocks`]'s pass for the states' block.
    #[inline(never)]
    fn solver_block(&mut self, at_point: bool) -> CallResult {
        let Some(lifting) = M::lifting() else {
            return Err(Failure::error("this FMU's model is written on f64 alone: it provides no exact derivatives"));
        };
        if !at_point {
            self.new_jacobians_point();
        }
        let j = &mut self.jacobians;
        // The layout checked the block's columns once (`solver_columns`): the states in
        // order, then at most the time, no field among them.
        let pass = StatesPass {
            t: self.state.t,
            x: &self.state.x,
            time: j.solver_columns > M::N_STATES,
            knowns: &j.seeds,
            fields: &j.fields,
            values: &j.known_values,
            values_at: j.fields_read_at,
            version: self.version,
        };
        (lifting.states)(&self.state.model, &pass, &mut j.lifted, &mut j.solver_block)
            .map_err(|e| Failure::error(format!("the parameters were refused: {e}")))?;
        j.solver_block_current = true;
        Ok(())
    }

    /// Makes the current point the blocks' (none computed there yet): its version, time and
    /// states, and the values of the knowns that are model fields.
    #[inline(always)]
    fn new_jacobians_point(&mut self) {
        let j = &mut self.jacobians;
        j.point = Some((self.version, self.state.t.to_bits()));
        // Over the model's constant number of states (a loop of known length): states of
        // another count never match (`at_jacobians_point` compares the lengths).
        // Sized once per layout, so no resize here (a cold one if ever not).
        let n = M::N_STATES;
        if j.x.len() != n {
            j.x.resize(n, 0);
        }
        if let Some(x) = j.x.get_mut(..n) {
            for (bits, v) in x.iter_mut().zip(&self.state.x) {
                *bits = v.to_bits();
            }
        }
        // While no input is driven, every write of a model field moves the version (a set, an
        // event, initialization, a reset, a restored state, input derivatives, the model's
        // communication-point work; `outputs` writes computed fields, never a known): the
        // values read at this version still hold. A driven input moves inside a step without
        // a set, and input derivatives set (a version moved) make one driven: read then.
        let held = self.state.drives.is_empty();
        if !(held && j.fields_read_at == Some(self.version)) {
            field_values(&self.table.rows, &j.knowns, &j.fields, &self.state.model, &mut j.known_values);
            j.fields_read_at = held.then_some(self.version);
        }
        j.done = Default::default();
        j.solver_block_current = false;
    }

    /// True when the cached Jacobian blocks were computed at the current point: the same
    /// version, time and states (to the bit).
    #[inline(always)]
    fn at_jacobians_point(&self) -> bool {
        let j = &self.jacobians;
        // Over the model's constant count of states, which `new_jacobians_point` keeps (the
        // loop unrolls): states of another count are not the point.
        let n = M::N_STATES;
        j.point == Some((self.version, self.state.t.to_bits()))
            && j.x.len() == n
            && self.state.x.len() == n
            && j.x[..n].iter().zip(&self.state.x[..n]).all(|(a, b)| *a == b.to_bits())
    }

    /// `fmi3GetAdjointDerivative`: `sensitivity = seed^T J` (one value per known, `seed` one
    /// per unknown), from the same Jacobian blocks.
    pub fn adjoint_derivative(
        &mut self,
        unknowns: &[u32],
        knowns: &[u32],
        seed: &[f64],
        sensitivity: &mut [f64],
        mode: Mode,
        function: &str,
    ) -> CallResult {
        if seed.len() != unknowns.len() || sensitivity.len() != knowns.len() {
            return Err(Failure::error(format!(
                "{function}: {} seed values for {} unknowns and room for {} sensitivities of {} knowns: give one per unknown and one per known",
                seed.len(),
                unknowns.len(),
                sensitivity.len(),
                knowns.len()
            )));
        }
        let rows = self.check_derivative_call(unknowns, knowns, mode, function)?;
        self.jacobian_blocks(rows, self.column_blocks(knowns), mode)?;
        let j = &self.jacobians;
        let width = j.knowns.len();
        let mut finite = true;
        for (out, &k) in sensitivity.iter_mut().zip(knowns) {
            let column = j.known_at[k as usize] as usize;
            let mut sum = 0.0;
            for (&place, &s) in j.asked_at.iter().zip(seed) {
                sum += j.values[place as usize * width + column] * s;
            }
            finite &= sum.is_finite();
            *out = sum;
        }
        if finite {
            Ok(())
        } else {
            Err(self.not_differentiable(sensitivity, knowns, false, function))
        }
    }

    /// The refusal of derivatives that are not all finite, naming the unknown (`by_unknown`) or
    /// the known the first belongs to.
    #[cold]
    #[inline(never)]
    fn not_differentiable(&self, values: &[f64], vrs: &[u32], by_unknown: bool, function: &str) -> Failure {
        let i = values.iter().position(|v| !v.is_finite()).expect("a value is not finite");
        let what = if by_unknown { "of" } else { "with respect to" };
        Failure::error(format!(
            "{function}: the derivative {what} '{}' is {} at t = {} s: the equations are not differentiable here",
            self.table.rows[vrs[i] as usize].name,
            values[i],
            self.time()
        ))
    }

    /// Makes the Jacobian blocks a call needs (its unknowns' row blocks `rows` in its knowns'
    /// column blocks `columns`) current: at a new point they are computed afresh, a block at
    /// a time as first needed.
    fn jacobian_blocks(&mut self, rows: Blocks, columns: Blocks, mode: Mode) -> CallResult {
        let Some(lifting) = M::lifting() else {
            return Err(Failure::error("this FMU's model is written on f64 alone: it provides no exact derivatives"));
        };
        if mode == Mode::Initialization {
            // The parameters checked and the initial state computed as the values are read.
            self.prepare_read(super::Phase::Initializing)?;
        }
        if !self.at_jacobians_point() {
            self.new_jacobians_point();
        }
        let j = &mut self.jacobians;
        let groups = [0..j.state_columns, j.state_columns..j.knowns.len()];
        for (row, derivatives) in [(0, true), (1, false)] {
            if !rows[row] {
                continue;
            }
            for (column, group) in groups.iter().enumerate() {
                if j.done[row][column] || !columns[column] || group.is_empty() {
                    continue;
                }
                let group = group.clone();
                let pass = Pass {
                    t: self.state.t,
                    x: &self.state.x,
                    knowns: &j.seeds,
                    fields: &j.fields,
                    values: &j.known_values,
                    seeded: group,
                    unknowns: if derivatives { &j.derivative_block } else { &j.other_block },
                    evaluates: if derivatives { j.derivative_evaluates } else { j.other_evaluates },
                    initialization: mode == Mode::Initialization,
                    version: self.version,
                };
                (lifting.forward)(&self.state.model, &pass, &mut j.lifted, &mut j.values)
                    .map_err(|e| Failure::error(format!("the parameters were refused: {e}")))?;
                j.done[row][column] = true;
            }
        }
        Ok(())
    }
}

impl<M: Model> Core<M> {
    /// `fmi2GetRealOutputDerivatives`, `fmi3GetOutputDerivatives`: `values[i]` = the
    /// `orders[i]`-th time derivative of the Real output `vrs[i]` at the current time, along
    /// the trajectory the FMU is on (its states moving as the right-hand side says, its inputs
    /// as their polynomials do, or held): exact, from the model's equations in dual numbers of
    /// the highest order asked for ([`trajectory`]). Orders 1 to [`MAX_ORDER`]; a discrete output's
    /// derivatives are 0. `function` names the call in messages.
    pub fn output_derivatives(&mut self, vrs: &[u32], orders: &[i32], values: &mut [f64], function: &str) -> CallResult {
        let Some(lifting) = M::lifting() else {
            return Err(Failure::error(format!(
                "{function}: this FMU's model is written on f64 alone: it provides no output derivatives (maxOutputDerivativeOrder=\"0\")"
            )));
        };
        let pass = &mut self.trajectory;
        // An importer asks for the same outputs and orders at every step: checked once.
        if !pass.request.is(vrs, orders) {
            pass.plan(&self.table, vrs, orders, function)?;
        }
        if self.planned_output_derivatives(lifting, values).map_err(|e| Failure::error(format!("{function}: {e}")))? {
            Ok(())
        } else {
            Err(self.not_differentiable(values, vrs, true, function))
        }
    }

    /// [`Core::output_derivatives`] when its checks are known to pass: the request of the last
    /// call (checked then), as a master makes it at every communication point. `None`
    /// otherwise, and when computing fails or a value is not finite (the full call computes
    /// again and explains). Else true, the values written.
    #[inline(always)]
    pub fn try_output_derivatives(&mut self, vrs: &[u32], orders: &[i32], values: &mut [f64]) -> Option<bool> {
        let lifting = M::lifting()?;
        // A master's usual requests, one output's orders 1 to 3 (Jacobi's extrapolation) or its
        // first derivative (Gauss-Seidel's interpolation), as arrays.
        let run = match vrs.len() {
            1 => self.try_output_run::<1>(lifting, vrs, orders, values),
            MAX_ORDER => self.try_output_run::<MAX_ORDER>(lifting, vrs, orders, values),
            _ => None,
        };
        if let Some(served) = run {
            return served;
        }
        if values.len() != vrs.len() || !self.trajectory.request.is(vrs, orders) {
            return None;
        }
        self.planned_output_derivatives(lifting, values).ok().filter(|&finite| finite)
    }

    /// [`Core::try_output_derivatives`] when the request is the kept [`super::Request::run`]
    /// of `K` orders (`None` otherwise): its one output's rates, of orders 1 to `K`.
    #[inline(always)]
    fn try_output_run<const K: usize>(
        &mut self,
        lifting: crate::model::Lifting<M>,
        vrs: &[u32],
        orders: &[i32],
        values: &mut [f64],
    ) -> Option<Option<bool>> {
        self.trajectory.request.run_of::<K>(vrs, orders)?;
        let values = <&mut [f64; K]>::try_from(values).ok()?;
        if !self.rates_current() && self.evaluate_trajectory(lifting).is_err() {
            return Some(None);
        }
        let Some(rates) = self.trajectory.rates.first() else { return Some(None) };
        values.copy_from_slice(&rates[..K]);
        Some(values.iter().sum::<f64>().is_finite().then_some(true))
    }

    /// The output derivatives of the kept plan (`self.trajectory`, made for the request) into
    /// `values`: whether they are all finite. Those of the current point when the outputs'
    /// evaluation computed them already ([`Core::shared_outputs`]).
    #[inline(always)]
    fn planned_output_derivatives(&mut self, lifting: crate::model::Lifting<M>, values: &mut [f64]) -> Result<bool, ModelError> {
        if !self.rates_current() {
            self.evaluate_trajectory(lifting)?;
        }
        let pass = &self.trajectory;
        let rates = pass.rates.as_flattened();
        let mut finite = true;
        for (value, &at) in values.iter_mut().zip(&pass.at) {
            // A place checked with the plan, but the rates are the pass's: no panic if not.
            *value = rates.get(at as usize).copied().unwrap_or(f64::NAN);
            finite &= value.is_finite();
        }
        Ok(finite)
    }
}

impl<M: Model> Core<M> {
    /// The kept plan's pass at the current point ([`trajectory`]); with
    /// [`Trajectory::shares_outputs`], the `f64` outputs too, which are then current. Inlined
    /// into the derivatives' call (a frame less per communication step).
    #[inline(always)]
    fn evaluate_trajectory(&mut self, lifting: crate::model::Lifting<M>) -> Result<(), ModelError> {
        // No call when no input is driven, nor was at the last pass (the road's case).
        if !(self.state.drives.is_empty() && self.trajectory.inputs.is_empty()) {
            self.input_derivatives();
        }
        let pass = &mut self.trajectory;
        (pass.t, pass.version, pass.current) = (self.state.t, self.version, false);
        (lifting.trajectory)(&mut self.state.model, &self.state.x, pass)?;
        if pass.shares_outputs {
            self.state.outputs_dirty = false;
            pass.current = true;
        }
        Ok(())
    }

    /// The kept plan's rates are those of the current point: the pass that found them also
    /// made the outputs current, and nothing moved since (any change of time, states, inputs,
    /// parameters or discrete state marks the outputs stale, or moves the version).
    #[inline(always)]
    fn rates_current(&self) -> bool {
        let pass = &self.trajectory;
        pass.current && !self.state.outputs_dirty && pass.version == self.version && pass.t == self.state.t
    }

    /// Brings the outputs up to date with the current point. A master that asks for output
    /// derivatives at every communication step (the kept plan, of any order, in [`Taylor3`],
    /// whose values are `f64`'s to the bit) reads the outputs there too: they come from the
    /// same pass as their derivatives, which the next [`Core::output_derivatives`] serves, instead of
    /// from a second evaluation of the model's outputs in `f64` (on the road, its sine and
    /// cosine again). Should the pass fail, `Model::outputs` in `f64`. Called only with
    /// [`Trajectory::shares_outputs`] (the other reads take the `f64` outputs in line).
    #[inline(never)]
    pub(super) fn shared_outputs(&mut self) {
        if let Some(lifting) = M::lifting() {
            if self.evaluate_trajectory(lifting).is_ok() {
                return;
            }
        }
        self.trajectory.current = false;
        self.state.refresh_outputs();
    }
}

impl Trajectory {
    /// Checks a request for the derivatives of orders `orders` of outputs `vrs` and makes
    /// `outputs` the unknowns it reads, each once, and `at` their places per value; the
    /// request is kept (`vrs`, `orders`) when valid.
    fn plan<M>(&mut self, table: &crate::table::Table<M>, vrs: &[u32], orders: &[i32], function: &str) -> CallResult {
        let rows = &table.rows;
        self.request.forget();
        (self.shares_outputs, self.current) = (false, false);
        self.outputs.clear();
        self.at.clear();
        for (&vr, &order) in vrs.iter().zip(orders) {
            let Some(row) = rows.get(vr as usize) else {
                return Err(Failure::error(format!("{function}: value reference {vr} is not a variable of this FMU")));
            };
            if row.causality != Causality::Output || row.base_type != BaseType::Real {
                return Err(Failure::error(format!(
                    "{function}: '{}' (value reference {vr}) is not a Real output: only those have output derivatives",
                    row.name
                )));
            }
            if !(1..=MAX_ORDER as i32).contains(&order) {
                return Err(Failure::error(format!(
                    "{function}: order {order} of '{}' refused: this FMU gives output derivatives of order 1 to {MAX_ORDER} (maxOutputDerivativeOrder)",
                    row.name
                )));
            }
            let unknown = match (&row.slot, row.field) {
                _ if row.variability != Variability::Continuous => Unknown::Zero,
                (Slot::Model(Access::State(k)), _) => Unknown::State(*k),
                (Slot::Model(Access::Real { .. }), Some(field)) => Unknown::Field(field),
                _ => Unknown::Zero,
            };
            let at = match self.outputs.iter().position(|&u| u == unknown) {
                Some(at) => at,
                None => {
                    self.outputs.push(unknown);
                    self.outputs.len() - 1
                }
            };
            self.at.push((at * MAX_ORDER + order as usize - 1) as u32);
        }
        self.request.keep(vrs, orders);
        self.reads_fields = self.outputs.iter().any(|u| matches!(u, Unknown::Field(_)));
        self.order = orders.iter().map(|&o| o as usize).max().unwrap_or(0);
        // The pass serves the f64 outputs when every value `Model::outputs` computes is a Real
        // field the pass has: it then runs in Taylor3 (values f64's to the bit) whatever the
        // order asked for, a Gauss-Seidel master's first derivative too.
        self.shared.clear();
        let mut shares = true;
        for (row, _) in rows.iter().zip(&table.computed).filter(|(_, &computed)| computed) {
            match (&row.slot, row.field) {
                (Slot::Model(Access::Real { .. }), Some(field)) => self.shared.push(field),
                _ => shares = false,
            }
        }
        self.shares_outputs = shares && !self.shared.is_empty();
        Ok(())
    }
}

/// Per output: its time derivatives of orders 1 to [`MAX_ORDER`] ([`trajectory`]).
pub type Rates = [f64; MAX_ORDER];

/// What [`trajectory`] evaluates, what it found, and what it keeps for the next call: a
/// polynomial coupling asks for output derivatives at every communication step, so an
/// instance keeps one of these, and its buffers and lifted model, from call to call.
#[derive(Default)]
pub struct Trajectory {
    /// The time of the point.
    pub t: f64,
    /// The instance's version (`Core::version`): a model lifted at the same version is the
    /// model's lift still.
    pub version: u64,
    /// The driven inputs: their model fields ([`crate::Lift::field`]), values and first
    /// [`MAX_ORDER`] time derivatives at `t` (the other inputs are held: derivatives 0).
    pub inputs: Vec<(usize, f64, Rates)>,
    /// The outputs of the request, each once (a master asks for several orders of one): a
    /// state, a model field, or `Zero`.
    pub outputs: Vec<Unknown>,
    /// Some of `outputs` are model fields: the outputs are evaluated (found with the plan).
    pub reads_fields: bool,
    /// The pass also gives the `f64` model its outputs (at the first read of one after a step):
    /// it runs in [`Taylor3`] and every value `Model::outputs` computes is one of the Real
    /// fields of `shared`, which take the pass's value parts.
    pub shares_outputs: bool,
    /// The fields (numbered as [`crate::Lift::field`]) of every value `Model::outputs`
    /// computes, when [`Trajectory::shares_outputs`].
    pub shared: Vec<usize>,
    /// `rates` are those of the point the outputs were last made current at (by this pass).
    pub(super) current: bool,
    /// Per value of the request: its place in `rates` read as one slice (its output's place in
    /// `outputs` times [`MAX_ORDER`], plus its order less one).
    at: Vec<u32>,
    /// The highest order asked for: the pass evaluates in dual numbers of that order (one
    /// pass of the right-hand side per order for the states' derivatives), and the rates
    /// above it are not read (an importer that passes first derivatives only costs one pass,
    /// in first-order dual numbers, or in [`Taylor3`] when that pass also gives the outputs).
    pub order: usize,
    /// The last valid request `outputs` was made for: value references and orders.
    request: super::Request,
    /// The result, per output of `outputs`.
    pub rates: Vec<Rates>,
    /// The model lifted into the dual numbers of the last pass (`M::Over<D>`, [`Taylor`])
    /// and the version it was lifted at. Between steps that set nothing, the parameters, held
    /// inputs and discrete state (what the lift copies) stay as they were; time and states are
    /// each pass's own, and the driven inputs are set at every pass. Lifting afresh
    /// (converting every field, cloning the model's strings and tables, dropping them again)
    /// cost more than the derivatives.
    lifted: KeptLift,
    /// Per state: its rates.
    state_rates: Vec<Rates>,
}

/// The first [`MAX_ORDER`] time derivatives of `pass.outputs` along the trajectory through
/// (`pass.t`, `x`), into `pass.rates`, by Taylor-mode forward differentiation: time, states
/// and inputs become dual numbers in the one direction of time (time's derivative 1, the
/// inputs' theirs), with as many derivative parts as the highest order asked for
/// (`pass.order`: [`Dual64`] for first derivatives, [`Dual2_64`] for second, third-order
/// [`Taylor3`] otherwise, whose constants cost less, and whenever the pass shares the outputs;
/// the rates above it are 0, but in a Taylor3 pass of a lower order, where they are no
/// derivatives and never read). The states' derivatives come from the
/// right-hand side itself, one order per pass: x' = f(x, u, t); the k-th derivative of f
/// along the trajectory needs the states' derivatives up to k only, so the pass with those
/// known gives x^(k+1) as f's k-th derivative part. The outputs, evaluated on the completed
/// states, then carry their derivatives. Exact to rounding, from the equations the simulation
/// runs. `#[derive(Variables)]` points [`crate::model::Lifting`] here.
///
/// With [`Trajectory::shares_outputs`], the outputs are evaluated whatever the request, and
/// `model`'s computed fields take their value parts (the `f64` outputs, to the bit).
pub fn trajectory<M: Model + Lift<Over<f64> = M>>(model: &mut M, x: &[f64], pass: &mut Trajectory) -> Result<(), ModelError>
where
    M::Over<Dual64>: Send + 'static,
    M::Over<Dual2_64>: Send + 'static,
    M::Over<Taylor3>: Send + 'static,
{
    // One call of the Taylor3 pass for every order it serves: it and the model's equations are
    // then inlined here (a frame and a call less, 35 instructions a step on the road).
    if pass.shares_outputs || pass.order > 2 {
        trajectory_in::<M, Taylor3>(model, x, pass)
    } else if pass.order == 2 {
        trajectory_in::<M, Dual2_64>(model, x, pass)
    } else {
        trajectory_in::<M, Dual64>(model, x, pass)
    }
}

/// [`trajectory`] in the dual numbers `D`.
fn trajectory_in<M: Model + Lift<Over<f64> = M>, D: Taylor + Send + 'static>(
    model: &mut M,
    x: &[f64],
    pass: &mut Trajectory,
) -> Result<(), ModelError>
where
    M::Over<D>: Send + 'static,
{
    let Lifted { model: lifted, x: xs, dx, .. } = pass.lifted.get::<M, D>(model, pass.version);
    for (f, value, d) in &pass.inputs {
        *M::field::<D>(lifted, *f) = D::taylor(*value, d);
    }
    if !pass.inputs.is_empty() {
        M::refresh_over::<D>(lifted);
    }
    let t = D::taylor(pass.t, &[1.0, 0.0, 0.0]);
    // The model's constant number of states (x has as many): the loops below then have a
    // known length, without bounds checks, unrolled for a few states.
    let n = M::N_STATES;
    let x = &x[..n];
    // The buffers are made with `n` states when lifted ([`KeptLift::lift`]), and stay so.
    pass.state_rates.resize(n, [0.0; MAX_ORDER]);
    let (xs, dx, rates) = (&mut xs[..n], &mut dx[..n], &mut pass.state_rates[..n]);
    for (lifted_x, &v) in xs.iter_mut().zip(x) {
        *lifted_x = D::from(v);
    }
    // Taylor3 serving a lower order (to share the outputs) leaves the parts above it 0 in the
    // states, and wrong in the outputs' rates: no request reads those (`Trajectory::at`).
    match pass.order {
        0 | 1 => state_rates::<M::Over<D>, D, 1>(lifted, t, xs, dx, rates),
        2 => state_rates::<M::Over<D>, D, 2>(lifted, t, xs, dx, rates),
        _ => state_rates::<M::Over<D>, D, MAX_ORDER>(lifted, t, xs, dx, rates),
    }
    if pass.reads_fields || pass.shares_outputs {
        lifted.outputs(t, xs);
    }
    if pass.shares_outputs {
        for &f in &pass.shared {
            *M::field::<f64>(model, f) = M::field::<D>(lifted, f).part(0);
        }
    }
    // Written in place: the request's outputs are the same from pass to pass.
    pass.rates.resize(pass.outputs.len(), [0.0; MAX_ORDER]);
    for (r, unknown) in pass.rates.iter_mut().zip(&pass.outputs) {
        *r = match *unknown {
            Unknown::State(k) => {
                let mut r = [0.0; MAX_ORDER];
                r[..D::ORDER].copy_from_slice(&rates[k][..D::ORDER]);
                r
            }
            Unknown::Field(f) => M::field::<D>(lifted, f).rates(),
            _ => [0.0; MAX_ORDER],
        };
    }
    Ok(())
}

/// Per state: its derivatives of orders 1 to `P` (`D::ORDER` at most), found one order per
/// pass of the right-hand side and given to the state's dual number for the next. `P` a
/// constant: the loop unrolled, each part found by its place.
#[inline(always)]
fn state_rates<L: Equations<D>, D: Taylor, const P: usize>(lifted: &L, t: D, xs: &mut [D], dx: &mut [D], rates: &mut [Rates]) {
    for order in 0..P.min(D::ORDER) {
        lifted.derivatives(t, xs, dx);
        for ((d, x), r) in dx.iter().zip(xs.iter_mut()).zip(rates.iter_mut()) {
            r[order] = d.part(order);
            x.set_part(order + 1, r[order]);
        }
    }
}

/// The dual numbers [`trajectory`] evaluates in: derivatives of orders 1 to `ORDER` along
/// time.
pub trait Taylor: crate::Scalar {
    /// The highest order it carries.
    const ORDER: usize;
    /// The number with value `value` and time derivatives `d` (those up to `ORDER`).
    fn taylor(value: f64, d: &Rates) -> Self;
    /// Its part of order `k` (0: the value).
    fn part(&self, k: usize) -> f64;
    /// Sets its part of order `k`, from 1 to `ORDER` (none above).
    fn set_part(&mut self, k: usize, value: f64);
    /// Its derivatives, 0 above `ORDER`.
    fn rates(&self) -> Rates;
}

impl Taylor for Dual64 {
    const ORDER: usize = 1;
    fn taylor(value: f64, d: &Rates) -> Self {
        Dual64::new(value, d[0])
    }
    fn part(&self, k: usize) -> f64 {
        [self.re, self.eps][k]
    }
    fn set_part(&mut self, k: usize, value: f64) {
        if k == 1 {
            self.eps = value;
        }
    }
    fn rates(&self) -> Rates {
        [self.eps, 0.0, 0.0]
    }
}

impl Taylor for Dual2_64 {
    const ORDER: usize = 2;
    fn taylor(value: f64, d: &Rates) -> Self {
        Dual2_64::new(value, d[0], d[1])
    }
    fn part(&self, k: usize) -> f64 {
        [self.re, self.v1, self.v2][k]
    }
    fn set_part(&mut self, k: usize, value: f64) {
        match k {
            1 => self.v1 = value,
            2 => self.v2 = value,
            _ => {}
        }
    }
    fn rates(&self) -> Rates {
        [self.v1, self.v2, 0.0]
    }
}

/// The parameters and literals constants: their products with the trajectory's numbers cost a
/// quarter (see [`crate::taylor3`]).
impl Taylor for Taylor3 {
    const ORDER: usize = 3;
    fn taylor(value: f64, d: &Rates) -> Self {
        Taylor3::varying(Dual3_64::taylor(value, d))
    }
    fn part(&self, k: usize) -> f64 {
        self.dual.part(k)
    }
    fn set_part(&mut self, k: usize, value: f64) {
        self.dual.set_part(k, value);
        self.constant = false;
    }
    fn rates(&self) -> Rates {
        self.dual.rates()
    }
}

impl Taylor for Dual3_64 {
    const ORDER: usize = 3;
    fn taylor(value: f64, d: &Rates) -> Self {
        Dual3_64::new(value, d[0], d[1], d[2])
    }
    fn part(&self, k: usize) -> f64 {
        [self.re, self.v1, self.v2, self.v3][k]
    }
    fn set_part(&mut self, k: usize, value: f64) {
        match k {
            1 => self.v1 = value,
            2 => self.v2 = value,
            3 => self.v3 = value,
            _ => {}
        }
    }
    fn rates(&self) -> Rates {
        [self.v1, self.v2, self.v3]
    }
}

/// A model lifted into the dual numbers `D` with its states' buffers: what a pass evaluates.
pub struct Lifted<L, D> {
    pub model: L,
    pub x: Vec<D>,
    pub dx: Vec<D>,
    /// When an implicit solver's pass ([`states`]) gave the field knowns their values unseeded
    /// and no other pass has given them since: the version those values were read at
    /// ([`StatesPass::values_at`]). The next such pass with values of that version has
    /// nothing to give.
    pub unseeded_at: Option<u64>,
}

/// Lifted models kept from pass to pass, one per number type (a Jacobian's blocks may take
/// different widths), each with the instance's version (`Core::version`) it was lifted at:
/// while the version stays, the parameters, held inputs and discrete state (what the lift
/// copies) are as they were, and each pass sets only its own time, states and seeded knowns.
/// Lifting afresh (converting every field, cloning the model's strings and tables, dropping
/// them again) cost more than the derivatives.
#[derive(Default)]
pub struct KeptLift(Vec<(std::any::TypeId, u64, Box<dyn std::any::Any + Send>)>);

impl KeptLift {
    /// `model` lifted into `D`: the kept one when lifted into `D` at `version`, else afresh.
    #[inline(always)]
    pub fn get<M: Model + Lift, D: crate::Scalar + Send + 'static>(&mut self, model: &M, version: u64) -> &mut Lifted<M::Over<D>, D>
    where
        M::Over<D>: Send + 'static,
    {
        // Found by its type's id, a constant here: asking each kept one for its type is a
        // dynamic call per entry.
        let kind = std::any::TypeId::of::<Lifted<M::Over<D>, D>>();
        let at = match self.0.iter().position(|(k, ..)| *k == kind) {
            Some(at) if self.0[at].1 == version => at,
            found => self.lift::<M, D>(model, version, found),
        };
        let kept: *mut (dyn std::any::Any + Send) = &mut *self.0[at].2;
        // SAFETY: every entry holds a value of the type whose id it is kept with, and entry
        // `at` is kept with `kind`'s. (`downcast_mut` would ask the value for its type again,
        // a dynamic call at every pass.)
        unsafe { &mut *kept.cast::<Lifted<M::Over<D>, D>>() }
    }

    /// [`KeptLift::get`] when nothing is kept for `D` at `version`: `model` lifted afresh into
    /// the entry `found` for `D` (lifted at another version), or a new one. Its place.
    #[cold]
    #[inline(never)]
    fn lift<M: Model + Lift, D: crate::Scalar + Send + 'static>(&mut self, model: &M, version: u64, found: Option<usize>) -> usize
    where
        M::Over<D>: Send + 'static,
    {
        // The states' buffers at their constant length: a pass then need not resize them.
        let zero = || vec![D::from(0.0); M::N_STATES];
        let lifted = Lifted { model: model.lift::<D>(), x: zero(), dx: zero(), unseeded_at: None };
        let entry = (std::any::TypeId::of::<Lifted<M::Over<D>, D>>(), version, Box::new(lifted) as Box<dyn std::any::Any + Send>);
        match found {
            Some(at) => {
                self.0[at] = entry;
                at
            }
            None => {
                self.0.push(entry);
                self.0.len() - 1
            }
        }
    }
}

/// Per known: the value of an input or parameter (a model field) in `model`, else 0, into
/// `out` (one value per known): what a pass seeds it with. Only the places `fields`
/// ([`field_places`]) are written; the others stay as they are (0).
pub fn field_values<M>(rows: &[Row<M>], knowns: &[usize], fields: &[usize], model: &M, out: &mut Vec<f64>) {
    out.resize(knowns.len(), 0.0);
    for &i in fields {
        if let Slot::Model(Access::Real { get, .. }) = rows[knowns[i]].slot {
            out[i] = get(model);
        }
    }
}

/// The places among `knowns` of the model fields: what a pass gives their values and seeds
/// (a scan of every known per pass cost quarter_car 100 instructions per Jacobian).
pub fn field_places(knowns: &[Known]) -> Vec<usize> {
    knowns.iter().enumerate().filter(|(_, k)| matches!(k, Known::Field(_))).map(|(i, _)| i).collect()
}

/// One known of a forward pass: what gets the derivative part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Known {
    /// The time.
    Time,
    /// State `k`.
    State(usize),
    /// The model's real field `k` (a parameter or input, see [`crate::Lift::field`]).
    Field(usize),
    /// A variable the equations do not read (a solver control): derivative 0.
    Constant,
}

/// One unknown of a forward pass: where its derivative parts are read.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Unknown {
    /// The time derivative of state `k`.
    Derivative(usize),
    /// State `k` (an initial unknown).
    State(usize),
    /// The model's real field `k` (an output, see [`crate::Lift::field`]).
    Field(usize),
    /// A variable the equations do not compute (derivative 0).
    Zero,
}

/// What one forward pass evaluates: the time and states it starts from, the knowns that get
/// unit seeds (a Jacobian column each) and the unknowns to read, each with its row of the
/// result (the other rows are left as they were).
pub struct Pass<'a> {
    pub t: f64,
    pub x: &'a [f64],
    pub knowns: &'a [Known],
    /// The places of the model fields among `knowns` ([`field_places`]).
    pub fields: &'a [usize],
    /// Per known: its value when a model field ([`field_values`]).
    pub values: &'a [f64],
    /// The knowns (their places) whose columns this pass computes; the others are unseeded.
    pub seeded: std::ops::Range<usize>,
    pub unknowns: &'a [(usize, Unknown)],
    /// What the unknowns need evaluated ([`Evaluates::of`]).
    pub evaluates: Evaluates,
    /// Initialization Mode: the states are unknowns, computed by `initial_state` from the
    /// (seeded) parameters.
    pub initialization: bool,
    /// The instance's version ([`KeptLift`]).
    pub version: u64,
}

/// The equations a pass evaluates for its unknowns.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Evaluates {
    /// The right-hand side (some unknowns are state derivatives).
    pub derivatives: bool,
    /// The outputs (some unknowns are model fields).
    pub outputs: bool,
}

impl Evaluates {
    /// What `unknowns` need evaluated.
    pub fn of(unknowns: &[(usize, Unknown)]) -> Evaluates {
        Evaluates {
            derivatives: unknowns.iter().any(|(_, u)| matches!(u, Unknown::Derivative(_))),
            outputs: unknowns.iter().any(|(_, u)| matches!(u, Unknown::Field(_))),
        }
    }
}

/// The number with value `value` and derivative part 1 in lane `lane` (0 elsewhere; no
/// derivative part at all for `None`).
#[inline]
fn seeded<const N: usize>(value: f64, lane: Option<usize>) -> DualSVec64<N> {
    match lane {
        Some(l) => {
            let mut e = SVector::<f64, N>::zeros();
            e[l] = 1.0;
            DualSVec64::new(value, Derivative::some(e))
        }
        None => DualSVec64::from(value),
    }
}

/// True when `number` is what [`seeded`] makes of `value` and `lane`, to the bit.
#[inline]
fn holds<const N: usize>(number: &DualSVec64<N>, value: f64, lane: Option<usize>) -> bool {
    number.re.to_bits() == value.to_bits()
        && match (&number.eps.0, lane) {
            (None, None) => true,
            (Some(e), Some(l)) => e.iter().enumerate().all(|(i, &v)| v.to_bits() == if i == l { 1f64 } else { 0f64 }.to_bits()),
            _ => false,
        }
}

/// The Jacobian of `model`'s equations at the pass's point: `out` (row-major, unknowns x
/// knowns) gets the derivative of each unknown with respect to each known, by forward passes
/// in vector dual numbers of up to [`LANES`] knowns each. The model's lift is kept in `kept`
/// between calls (lifted afresh at initialization, whose `initial_state` may change it); each
/// pass seeds the knowns, computes the seeded parameters' derived fields again, and evaluates
/// only what the unknowns need. `#[derive(Variables)]` points [`crate::model::Lifting`] here.
pub fn forward<M: Model + Lift>(model: &M, pass: &Pass, kept: &mut KeptLift, out: &mut [f64]) -> Result<(), ModelError>
where
    M::Over<DualSVec64<2>>: Send + 'static,
    M::Over<DualSVec64<4>>: Send + 'static,
    M::Over<DualSVec64<6>>: Send + 'static,
    M::Over<DualSVec64<LANES>>: Send + 'static,
{
    // Fewer knowns than LANES (a model with a few states, its states' columns) take narrower
    // numbers: each lane costs its share of every operation whether seeded or not (quarter_car's
    // 5 states in 6 lanes rather than 8: 3311 -> 3089 instructions per Jacobian).
    match pass.seeded.len() {
        0..=2 => forward_in::<M, 2>(model, pass, kept, out),
        3..=4 => forward_in::<M, 4>(model, pass, kept, out),
        5..=6 => forward_in::<M, 6>(model, pass, kept, out),
        _ => forward_in::<M, LANES>(model, pass, kept, out),
    }
}

/// What an implicit solver's pass ([`states`]) evaluates: d(der x)/d(x[, t]) at `t` and `x`,
/// the states seeded in order, then the time when `time`. Every model field among `knowns`
/// ([`Pass`]'s: their places `fields`, their values `values`) gets its value unseeded. A
/// Jacobian's layout checks its block's columns once, so the pass itself has nothing to check
/// but its sizes.
pub struct StatesPass<'a> {
    pub t: f64,
    pub x: &'a [f64],
    /// The time's column follows the states'.
    pub time: bool,
    pub knowns: &'a [Known],
    pub fields: &'a [usize],
    pub values: &'a [f64],
    /// The instance's version `values` were read at, when they hold until it moves; `None`
    /// when they may differ at every point (a driven input).
    pub values_at: Option<u64>,
    /// The instance's version ([`KeptLift`]).
    pub version: u64,
}

/// The block d(der x)/d(x[, t]) of an implicit solver's pass, column by column into `out`
/// (`out[l * n + k]`: state derivative `k` in state `l`'s column, then the time's, `n`
/// states), in one pass of dual numbers at least 4 lanes wide: each lane's arithmetic is the
/// same as in [`forward`]'s narrower numbers, so the values are the same to the bit, without
/// the general pass's loops over chunks, knowns and unknowns. Two lanes are not used here: a
/// two-state block in 2 lanes took mass_spring_damper's Jacobian 0.077 us against 0.060 us in
/// 4, for about the same instructions (1,026 against 1,017): the narrow numbers' code runs
/// slower per instruction (measured in time, the judge). `#[derive(Variables)]` points
/// [`crate::model::Lifting`] here; `Core::solver_block`, its one caller, takes it inlined
/// through that constant (a frame less, and the pass's fields not laid out in memory).
#[inline(always)]
pub fn states<M: Model + Lift>(model: &M, pass: &StatesPass, kept: &mut KeptLift, out: &mut [f64]) -> Result<(), ModelError>
where
    M::Over<DualSVec64<4>>: Send + 'static,
    M::Over<DualSVec64<6>>: Send + 'static,
    M::Over<DualSVec64<LANES>>: Send + 'static,
{
    let n = M::N_STATES;
    let lanes = n + usize::from(pass.time);
    match lanes {
        _ if pass.x.len() != n || out.len() != lanes * n => Err(ModelError("an implicit solver's pass of the wrong size".into())),
        // Not 2 lanes for 1 or 2 knowns: see above.
        1..=4 => states_in::<M, 4>(model, pass, kept, out),
        5..=6 => states_in::<M, 6>(model, pass, kept, out),
        7..=LANES => states_in::<M, LANES>(model, pass, kept, out),
        _ => Err(ModelError(format!("an implicit solver's pass is at least one and at most {LANES} knowns wide"))),
    }
}

/// [`states`] in dual numbers of `N` lanes, `pass` checked to fit them.
fn states_in<M: Model + Lift, const N: usize>(model: &M, pass: &StatesPass, kept: &mut KeptLift, out: &mut [f64]) -> Result<(), ModelError>
where
    M::Over<DualSVec64<N>>: Send + 'static,
{
    let Lifted { model: lifted, x, dx, unseeded_at } = kept.get::<M, DualSVec64<N>>(model, pass.version);
    // No field is among this pass's seeded knowns: they all get their values unseeded, said
    // by an empty range the compiler sees (no lane to find per field); not again while they
    // hold the same values so (the last pass was one of these, with values of one version).
    if !(pass.values_at.is_some() && *unseeded_at == pass.values_at) {
        give_fields::<M, N>(lifted, pass.knowns, pass.fields, pass.values, &(0..0));
        *unseeded_at = pass.values_at;
    }
    // The model's constant number of states: the loops below have a known length.
    let n = M::N_STATES;
    // The lift made them the model's constant length ([`KeptLift::lift`]): no resize per pass.
    let (Some(x), Some(dx)) = (x.get_mut(..n), dx.get_mut(..n)) else {
        return Err(ModelError("the lifted states' buffers are not the model's length".into()));
    };
    for (l, (x, &v)) in x.iter_mut().zip(&pass.x[..n]).enumerate() {
        *x = seeded(v, Some(l));
    }
    let t = seeded(pass.t, pass.time.then_some(n));
    lifted.derivatives(t, x, dx);
    // State derivative by state derivative, so a derivative's "no part" (it depends on no
    // known) is one branch, not one per column; the columns are slices of the states' length
    // (indexing out[l * n + k] cost quarter_car about 100 instructions more).
    for (k, d) in dx.iter().enumerate() {
        match &d.eps.0 {
            Some(e) => {
                for (column, &v) in out.chunks_exact_mut(n).zip(e.iter()) {
                    column[k] = v;
                }
            }
            None => {
                for column in out.chunks_exact_mut(n) {
                    column[k] = 0.0;
                }
            }
        }
    }
    Ok(())
}

/// Every field among a pass's `knowns` (their places `fields`, [`Pass`]'s) gets its value in
/// `lifted`, seeded in the pass's `lanes` and unseeded otherwise. A kept lift already holds the last pass's: only a change is written, and
/// then the derived fields are computed again.
#[inline(always)]
fn give_fields<M: Model + Lift, const N: usize>(
    lifted: &mut M::Over<DualSVec64<N>>,
    knowns: &[Known],
    fields: &[usize],
    values: &[f64],
    lanes: &std::ops::Range<usize>,
) {
    let mut changed = false;
    for &i in fields {
        if let Known::Field(f) = knowns[i] {
            let lane = lanes.contains(&i).then(|| i - lanes.start);
            let field = M::field(lifted, f);
            if !holds(field, values[i], lane) {
                *field = seeded(values[i], lane);
                changed = true;
            }
        }
    }
    if changed {
        M::refresh_over(lifted);
    }
}

/// [`forward`] in passes of `N` knowns each.
fn forward_in<M: Model + Lift, const N: usize>(model: &M, pass: &Pass, kept: &mut KeptLift, out: &mut [f64]) -> Result<(), ModelError>
where
    M::Over<DualSVec64<N>>: Send + 'static,
{
    let mut fresh;
    let Lifted { model: lifted, x, dx, unseeded_at } = if pass.initialization {
        fresh = Lifted { model: model.lift(), x: Vec::new(), dx: Vec::new(), unseeded_at: None };
        &mut fresh
    } else {
        kept.get::<M, DualSVec64<N>>(model, pass.version)
    };
    let width = pass.knowns.len();
    let Evaluates { derivatives, outputs } = pass.evaluates;
    dx.resize(pass.x.len(), DualSVec64::from(0.0));
    let first = pass.seeded.start;
    for (chunk, knowns) in pass.knowns[pass.seeded.clone()].chunks(N).enumerate() {
        let lanes = first + chunk * N..first + chunk * N + knowns.len();
        if pass.initialization && chunk > 0 {
            // The last chunk's `initial_state` may have changed the model's fields.
            *lifted = model.lift();
        }
        give_fields::<M, N>(lifted, pass.knowns, pass.fields, pass.values, &lanes);
        *unseeded_at = None;
        let mut t = DualSVec64::from(pass.t);
        x.clear();
        // The usual chunk, an implicit solver's: the states first and in order, each seeded as
        // it is made (not made unseeded, then found and seeded again).
        let n = pass.x.len();
        let in_order = knowns.len() >= n && knowns[..n].iter().enumerate().all(|(l, k)| *k == Known::State(l));
        let rest = if in_order {
            x.extend(pass.x.iter().enumerate().map(|(l, &v)| seeded(v, Some(l))));
            n
        } else {
            x.extend(pass.x.iter().map(|&v| DualSVec64::from(v)));
            0
        };
        for (l, known) in knowns.iter().enumerate().skip(rest) {
            match *known {
                Known::Time => t = seeded(pass.t, Some(l)),
                Known::State(k) => x[k] = seeded(pass.x[k], Some(l)),
                _ => {}
            }
        }
        if pass.initialization {
            lifted.initial_state(x)?;
        }
        if derivatives {
            lifted.derivatives(t, x, dx);
        }
        if outputs {
            lifted.outputs(t, x);
        }
        for &(i, unknown) in pass.unknowns {
            let eps = match unknown {
                Unknown::Derivative(k) => dx[k].eps.0.as_ref(),
                Unknown::State(k) => x[k].eps.0.as_ref(),
                Unknown::Field(f) => M::field(lifted, f).eps.0.as_ref(),
                Unknown::Zero => None,
            };
            let row = &mut out[i * width + lanes.start..][..knowns.len()];
            match eps {
                Some(e) => row.copy_from_slice(&e.as_slice()[..knowns.len()]),
                None => row.fill(0.0),
            }
        }
    }
    Ok(())
}

/// Checks model `M`'s implicit-solver path ([`Core::try_directional_derivative`] with the
/// state derivatives as unknowns and one state as known, as an importer asks for d(der x)/dx
/// column by column, answered from [`states`]'s one pass) against the general path
/// ([`Core::directional_derivative`], whose blocks come from [`forward`]) at `points` (model,
/// time, states: its discrete state and regime as the run had them there): the same values
/// to the bit, in Continuous-Time Mode. At each point, on one instance: the solver's columns
/// first; then, the states moved by 1e-3 relative, the general ones first; then, moved again,
/// against one general call per column that seeds every state (0 but for the column's);
/// then at the same time and states after each Real input is set to another value, and after
/// an event update: so neither path answers from the other's block, nor from one of another
/// point, input or regime. Model Exchange through the instance's core, as the C functions
/// reach it. The columns compared.
pub fn check_solver_block<M: Model>(points: &[(M, f64, Vec<f64>)]) -> Result<usize, String> {
    let names = super::Names { setup: "setup", exit_initialization: "exit", real: "Real", integer: "Integer" };
    let mut compared = 0;
    for (model, t, x) in points {
        let mut core = Core::<M>::new("check", crate::logging::Logger::new(None, false), names);
        core.setup(None, 0.0, None).map_err(|e| e.message)?;
        core.start_exchange().map_err(|e| e.message)?;
        core.state.model = model.clone();
        // A write of the model's fields: what was derived from them is stale.
        core.version += 1;
        let rows = &core.table.rows;
        let find = |want: &dyn Fn(&Slot<M>) -> bool| -> Result<Vec<u32>, String> {
            (0..M::N_STATES)
                .map(|k| {
                    let at = rows
                        .iter()
                        .position(|r| want(&r.slot) && matches!(r.slot, Slot::Derivative(j) | Slot::Model(Access::State(j)) if j == k));
                    at.map(|i| i as u32).ok_or_else(|| format!("state {k} has no variable"))
                })
                .collect()
        };
        let derivatives = find(&|slot| matches!(slot, Slot::Derivative(_)))?;
        let states = find(&|slot| matches!(slot, Slot::Model(Access::State(_))))?;
        let inputs: Vec<u32> = (0..rows.len())
            .filter(|&i| rows[i].causality == Causality::Input && rows[i].base_type == BaseType::Real && rows[i].field.is_some())
            .map(|i| i as u32)
            .collect();
        let request = SolverRequest { derivatives: &derivatives, states: &states };
        for (round, order) in [Order::SolverFirst, Order::GeneralFirst, Order::AllSeeded].into_iter().enumerate() {
            let moved: Vec<f64> = x.iter().map(|v| v + round as f64 * 1e-3 * v.abs().max(1.0)).collect();
            core.set_time(*t).map_err(|e| e.message)?;
            core.set_continuous_states(&moved).map_err(|e| e.message)?;
            compared += request.compare(&mut core, order, &format!("t = {t}, x = {moved:?}"))?;
        }
        for &input in &inputs {
            let mut value = [0.0];
            core.get_real(&[input], &mut value, super::Phase::ContinuousTime).map_err(|e| e.message)?;
            core.set_real(&[input], &[value[0] * 1.5 + 0.25], super::Phase::ContinuousTime, "ContinuousTimeMode").map_err(|e| e.message)?;
            let name = core.table.rows[input as usize].name;
            compared += request.compare(&mut core, Order::SolverFirst, &format!("t = {t}, after '{name}' was set"))?;
        }
        let update = core.event_update().map_err(|e| e.message)?;
        if !update.terminate_simulation {
            core.enter_continuous_time().map_err(|e| e.message)?;
            compared += request.compare(&mut core, Order::SolverFirst, &format!("t = {t}, after an event update"))?;
        }
    }
    Ok(compared)
}

/// Which path [`check_solver_block`] asks first at a point, or the general path by calls
/// that seed every state.
#[derive(Clone, Copy, PartialEq)]
enum Order {
    SolverFirst,
    GeneralFirst,
    AllSeeded,
}

/// The value references of an implicit solver's request: the state derivatives and the
/// states, in the states' order.
struct SolverRequest<'a> {
    derivatives: &'a [u32],
    states: &'a [u32],
}

impl SolverRequest<'_> {
    /// d(der x)/dx at `core`'s point by the solver's path and by the general one (in `order`),
    /// compared to the bit; `at` says where, for the message. The columns compared.
    fn compare<M: Model>(&self, core: &mut Core<M>, order: Order, at: &str) -> Result<usize, String> {
        let n = self.states.len();
        let mut general = vec![0.0; n * n];
        let mut solver = vec![0.0; n * n];
        let solver_first = order == Order::SolverFirst;
        for by_solver in [solver_first, !solver_first] {
            for (j, &known) in self.states.iter().enumerate() {
                let column = &mut if by_solver { &mut solver } else { &mut general }[j * n..][..n];
                if by_solver {
                    // The first call of a new request is the general path's, which checks it.
                    if core.jacobians.asked != self.derivatives {
                        core.directional_derivative(self.derivatives, &[known], &[1.0], column, Mode::ContinuousTime, "check")
                            .map_err(|e| e.message)?;
                    }
                    match core.try_directional_derivative(self.derivatives, &[known], &[1.0], column, Mode::ContinuousTime) {
                        Some(true) => {}
                        other => return Err(format!("{at}: the solver's column {j} was not answered in place: {other:?}")),
                    }
                } else if order == Order::AllSeeded {
                    let seed: Vec<f64> = (0..n).map(|i| if i == j { 1.0 } else { 0.0 }).collect();
                    core.directional_derivative(self.derivatives, self.states, &seed, column, Mode::ContinuousTime, "check")
                        .map_err(|e| e.message)?;
                } else {
                    core.directional_derivative(self.derivatives, &[known], &[1.0], column, Mode::ContinuousTime, "check")
                        .map_err(|e| e.message)?;
                }
            }
        }
        let j = &core.jacobians;
        if j.state_columns <= LANES && !(j.solver_columns > 0 && j.asked_derivatives && j.solver_block_current) {
            return Err(format!("{at}: the solver's columns did not come from the solver's block"));
        }
        if solver.iter().map(|v| v.to_bits()).ne(general.iter().map(|v| v.to_bits())) {
            return Err(format!("{at}: the solver's d(der x)/dx (by columns) {solver:?}, the general path's {general:?}"));
        }
        Ok(n)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use serde::{Deserialize, Serialize};

    use super::Mode;
    use crate::core::{Core, Names, Phase};
    use crate::logging::{Logger, Status};
    use crate::model::{Equations, EventOutcome, Model, ModelError, ModelInfo};
    use crate::{Scalar, StateVector, Variables};

    /// x' = -k x + u, y = x^2 + u: small enough that every derivative is known by hand.
    #[derive(Debug, Clone, Serialize, Deserialize, Variables)]
    #[variables(states = S)]
    pub(crate) struct Decay<T = f64> {
        /// Rate constant
        #[parameter]
        k: T,
        /// Initial value
        #[parameter]
        x0: T,
        /// Input
        #[input]
        u: T,
        /// Output x^2 + u
        #[output]
        y: T,
    }

    #[derive(StateVector)]
    struct S<T = f64> {
        /// The state
        x: T,
    }

    impl Default for Decay {
        fn default() -> Self {
            Decay { k: 2.0, x0: 3.0, u: 0.5, y: 0.0 }
        }
    }

    impl<T: Scalar> Equations<T> for Decay<T> {
        fn initial_state(&mut self, x: &mut [T]) -> Result<(), ModelError> {
            S { x: self.x0 }.store(x);
            Ok(())
        }

        fn derivatives(&self, _t: T, x: &[T], dx: &mut [T]) {
            let S { x } = S::load(x);
            S { x: -self.k * x + self.u }.store(dx);
        }

        fn outputs(&mut self, _t: T, x: &[T]) {
            let S { x } = S::load(x);
            self.y = x * x + self.u;
        }
    }

    impl Model for Decay {
        const N_STATES: usize = 1;

        fn info() -> ModelInfo {
            ModelInfo { identifier: "decay", description: "", stop_time: 1.0, tolerance: 1e-6, output_interval: 0.1, documentation: "" }
        }
    }

    const NAMES: Names = Names { setup: "setup", exit_initialization: "exit", real: "Real", integer: "Integer" };

    fn vr(core: &Core<Decay>, name: &str) -> u32 {
        core.table().rows.iter().position(|r| r.name == name).unwrap_or_else(|| panic!("{name}")) as u32
    }

    /// A Model Exchange instance in continuous time at x = 1.5 (k = 2, u = 0.5).
    fn continuous() -> Core<Decay> {
        let mut core = Core::<Decay>::new("decay", Logger::new(None, false), NAMES);
        core.setup(None, 0.0, None).unwrap();
        core.start_exchange().unwrap();
        core.set_continuous_states(&[1.5]).unwrap();
        core
    }

    /// der(x) = -k x + u and y = x^2 + u against their derivatives by hand, in one directional
    /// derivative per known and in one combined seed: exactly, as the equations are
    /// polynomials evaluated once.
    #[test]
    fn continuous_time_derivatives_are_those_by_hand() {
        let mut core = continuous();
        let (der, y, x, u, t) = (vr(&core, "der(x)"), vr(&core, "y"), vr(&core, "x"), vr(&core, "u"), vr(&core, "time"));
        let mut out = [0.0; 2];
        let dd = |core: &mut Core<Decay>, knowns: &[u32], seed: &[f64], out: &mut [f64; 2]| {
            core.directional_derivative(&[der, y], knowns, seed, out, Mode::ContinuousTime, "test").unwrap()
        };
        dd(&mut core, &[x], &[1.0], &mut out);
        assert_eq!(out, [-2.0, 3.0]);
        dd(&mut core, &[u], &[1.0], &mut out);
        assert_eq!(out, [1.0, 1.0]);
        dd(&mut core, &[t], &[1.0], &mut out);
        assert_eq!(out, [0.0, 0.0]);
        dd(&mut core, &[x, u], &[2.0, -1.0], &mut out);
        assert_eq!(out, [-5.0, 5.0]);
        // The adjoint is the transpose: seed^T J over the knowns x and u.
        let mut adjoint = [0.0; 2];
        core.adjoint_derivative(&[der, y], &[x, u], &[1.0, 10.0], &mut adjoint, Mode::ContinuousTime, "test").unwrap();
        assert_eq!(adjoint, [-2.0 + 30.0, 1.0 + 10.0]);
        // The Jacobian the first call computed is that of its point: new states, a new one.
        core.set_continuous_states(&[2.0]).unwrap();
        dd(&mut core, &[x], &[1.0], &mut out);
        assert_eq!(out, [-2.0, 4.0]);
    }

    /// The states' columns and the others' are computed by separate passes on the kept lifted
    /// model, in the order the importer asks for them: the input seeded for its column must
    /// be unseeded again for the states' (else its lane adds d/du to a state's column), and
    /// an input set between calls (a new lift) changes nothing of that. By hand at x = 1.5,
    /// then 2: d der/dx = -k = -2, d der/du = 1, dy/dx = 2 x, dy/du = 1. Through the in-place
    /// route (a column of the last call's unknowns) and the general one.
    #[test]
    fn state_and_input_columns_by_separate_passes_are_those_by_hand() {
        let mut core = continuous();
        let (der, y, x, u) = (vr(&core, "der(x)"), vr(&core, "y"), vr(&core, "x"), vr(&core, "u"));
        let mut out = [0.0; 2];
        let dd = |core: &mut Core<Decay>, known: u32, out: &mut [f64; 2]| {
            core.directional_derivative(&[der, y], &[known], &[1.0], out, Mode::ContinuousTime, "test").unwrap()
        };
        let in_place = |core: &mut Core<Decay>, known: u32, out: &mut [f64; 2]| {
            assert_eq!(core.try_directional_derivative(&[der, y], &[known], &[1.0], out, Mode::ContinuousTime), Some(true));
        };
        dd(&mut core, x, &mut out);
        assert_eq!(out, [-2.0, 3.0]);
        in_place(&mut core, u, &mut out);
        assert_eq!(out, [1.0, 1.0]);
        core.set_continuous_states(&[2.0]).unwrap();
        in_place(&mut core, u, &mut out);
        assert_eq!(out, [1.0, 1.0]);
        in_place(&mut core, x, &mut out);
        assert_eq!(out, [-2.0, 4.0]);
        core.set_real(&[u], &[4.0], Phase::Running, "ContinuousTimeMode").unwrap();
        dd(&mut core, u, &mut out);
        assert_eq!(out, [1.0, 1.0]);
        in_place(&mut core, x, &mut out);
        assert_eq!(out, [-2.0, 4.0]);
        dd(&mut core, x, &mut out);
        assert_eq!(out, [-2.0, 4.0]);
    }

    /// x' = -k u x, y = u x: the states' Jacobian (d der(x)/dx = -k u, dy/dx = u) depends on
    /// a tunable parameter and on the input, which the dual passes' kept lift holds.
    #[derive(Debug, Clone, Serialize, Deserialize, Variables)]
    #[variables(states = S)]
    struct Scaled<T = f64> {
        /// Rate constant
        #[parameter(tunable)]
        k: T,
        /// Input
        #[input]
        u: T,
        /// Output u x
        #[output]
        y: T,
    }

    impl Default for Scaled {
        fn default() -> Self {
            Scaled { k: 2.0, u: 0.5, y: 0.0 }
        }
    }

    impl<T: Scalar> Equations<T> for Scaled<T> {
        fn initial_state(&mut self, x: &mut [T]) -> Result<(), ModelError> {
            S { x: T::one() }.store(x);
            Ok(())
        }

        fn derivatives(&self, _t: T, x: &[T], dx: &mut [T]) {
            let S { x } = S::load(x);
            S { x: -self.k * self.u * x }.store(dx);
        }

        fn outputs(&mut self, _t: T, x: &[T]) {
            let S { x } = S::load(x);
            self.y = self.u * x;
        }
    }

    impl Model for Scaled {
        const N_STATES: usize = 1;

        fn info() -> ModelInfo {
            ModelInfo { identifier: "scaled", description: "", stop_time: 1.0, tolerance: 1e-6, output_interval: 0.1, documentation: "" }
        }
    }

    /// The Jacobian blocks and the lifted model are kept from call to call while the point
    /// stays: an input set (Continuous-Time Mode) or a tunable parameter set (Event Mode)
    /// between two Jacobians at the same time and states, in the same mode, must give the
    /// new Jacobian, through the general route and the in-place one an importer's columns
    /// take. By hand: d der(x)/dx = -k u, dy/dx = u, exactly (products of exact values).
    #[test]
    fn a_parameter_or_input_set_between_jacobians_at_the_same_states_gives_the_new_jacobian() {
        let mut core = Core::<Scaled>::new("scaled", Logger::new(None, false), NAMES);
        core.setup(None, 0.0, None).unwrap();
        core.start_exchange().unwrap();
        core.set_continuous_states(&[1.5]).unwrap();
        let row = |name: &str| core.table().rows.iter().position(|r| r.name == name).unwrap() as u32;
        let (der, y, x, k, u) = (row("der(x)"), row("y"), row("x"), row("k"), row("u"));
        let general = |core: &mut Core<Scaled>, mode: Mode| {
            let mut out = [0.0; 2];
            core.directional_derivative(&[der, y], &[x], &[1.0], &mut out, mode, "test").unwrap();
            out
        };
        let in_place = |core: &mut Core<Scaled>, mode: Mode| {
            let mut out = [0.0; 2];
            assert_eq!(core.try_directional_derivative(&[der, y], &[x], &[1.0], &mut out, mode), Some(true));
            out
        };
        // k = 2, u = 0.5.
        assert_eq!(general(&mut core, Mode::ContinuousTime), [-1.0, 0.5]);
        core.set_real(&[u], &[3.0], Phase::ContinuousTime, "ContinuousTimeMode").unwrap();
        assert_eq!(in_place(&mut core, Mode::ContinuousTime), [-6.0, 3.0]);
        core.set_real(&[u], &[4.0], Phase::ContinuousTime, "ContinuousTimeMode").unwrap();
        assert_eq!(general(&mut core, Mode::ContinuousTime), [-8.0, 4.0]);
        // Event Mode, where the tunable parameter may be set: k = 2, u = 4, then k = 5.
        assert_eq!(general(&mut core, Mode::Event), [-8.0, 4.0]);
        core.set_real(&[k], &[5.0], Phase::Event, "EventMode").unwrap();
        assert_eq!(in_place(&mut core, Mode::Event), [-20.0, 4.0]);
        core.set_real(&[k], &[0.25], Phase::Event, "EventMode").unwrap();
        assert_eq!(general(&mut core, Mode::Event), [-1.0, 4.0]);
        // The states did not move: the Jacobians differ by the sets alone.
        let mut states = [0.0];
        core.continuous_states(&mut states, false).unwrap();
        assert_eq!(states, [1.5]);
    }

    /// An implicit solver's column: unknowns the state derivatives, one state seeded, answered
    /// in place from the solver's block ([`super::states`]); its value.
    fn solver_column<M: Model>(core: &mut Core<M>, unknowns: &[u32], known: u32) -> f64 {
        let mut out = [0.0];
        assert_eq!(core.try_directional_derivative(unknowns, &[known], &[1.0], &mut out, Mode::ContinuousTime), Some(true));
        assert!(core.jacobians.solver_block_current, "answered from the solver's block");
        out[0]
    }

    /// The implicit solver's block is kept while the point stays: an input set (Continuous-Time
    /// Mode) or a tunable parameter set (Event Mode) between two of its Jacobians at the same
    /// time and states must give the new one (a stale block would repeat the old one). By
    /// hand: d der(x)/dx = -k u, exactly.
    #[test]
    fn the_solver_block_follows_a_set_at_the_same_states() {
        let mut core = Core::<Scaled>::new("scaled", Logger::new(None, false), NAMES);
        core.setup(None, 0.0, None).unwrap();
        core.start_exchange().unwrap();
        core.set_continuous_states(&[1.5]).unwrap();
        let row = |name: &str| core.table().rows.iter().position(|r| r.name == name).unwrap() as u32;
        let (der, x, k, u) = (row("der(x)"), row("x"), row("k"), row("u"));
        // The request is checked by the general path first, as the C function's first call is.
        let mut out = [0.0];
        core.directional_derivative(&[der], &[x], &[1.0], &mut out, Mode::ContinuousTime, "test").unwrap();
        assert_eq!(out, [-1.0]);
        assert_eq!(solver_column(&mut core, &[der], x), -1.0);
        core.set_real(&[u], &[3.0], Phase::ContinuousTime, "ContinuousTimeMode").unwrap();
        assert_eq!(solver_column(&mut core, &[der], x), -6.0);
        core.set_real(&[k], &[5.0], Phase::Event, "EventMode").unwrap();
        assert_eq!(solver_column(&mut core, &[der], x), -15.0);
        let mut states = [0.0];
        core.continuous_states(&mut states, false).unwrap();
        assert_eq!(states, [1.5], "the states did not move: the Jacobians differ by the sets alone");
    }

    /// x1' = u x2 + w, x2' = -k u x1: two states and two inputs, so the general pass of the
    /// columns of the time and the inputs (three knowns) takes numbers of 4 lanes as the
    /// solver's pass of two states does (the same kept lift), and u's lane there is a state's
    /// in the solver's.
    #[derive(Debug, Clone, Serialize, Deserialize, Variables)]
    #[variables(states = S2)]
    struct Swing<T = f64> {
        /// Rate constant
        #[parameter]
        k: T,
        /// Input
        #[input]
        u: T,
        /// A second input, so that the inputs' pass is as wide as the solver's
        #[input]
        w: T,
    }

    #[derive(StateVector)]
    struct S2<T = f64> {
        /// The first state
        x1: T,
        /// The second state
        x2: T,
    }

    impl Default for Swing {
        fn default() -> Self {
            Swing { k: 2.0, u: 0.5, w: 0.0 }
        }
    }

    impl<T: Scalar> Equations<T> for Swing<T> {
        fn initial_state(&mut self, x: &mut [T]) -> Result<(), ModelError> {
            S2 { x1: T::from(1.5), x2: T::from(-0.5) }.store(x);
            Ok(())
        }

        fn derivatives(&self, _t: T, x: &[T], dx: &mut [T]) {
            let S2 { x1, x2 } = S2::load(x);
            S2 { x1: self.u * x2 + self.w, x2: -self.k * self.u * x1 }.store(dx);
        }
    }

    impl Model for Swing {
        const N_STATES: usize = 2;

        fn info() -> ModelInfo {
            ModelInfo { identifier: "swing", description: "", stop_time: 1.0, tolerance: 1e-6, output_interval: 0.1, documentation: "" }
        }
    }

    /// The solver's pass gives the field knowns their values unseeded only when the last pass
    /// on its kept lift was not one of its own with values of the same version: a general pass
    /// in between (the input's column, u seeded) must be undone at the next new point of the
    /// same version, or u's derivative [x2, -k x1] adds to a state's column (seen: x1's became
    /// [0.75, -5]). By hand (k = 2, u = 0.5): the columns d der(x)/dx1 = [0, -k u] = [0, -1]
    /// and d der(x)/dx2 = [u, 0] = [0.5, 0] at every point, exactly.
    #[test]
    fn the_solver_block_unseeds_an_input_a_general_pass_seeded() {
        let mut core = Core::<Swing>::new("swing", Logger::new(None, false), NAMES);
        core.setup(None, 0.0, None).unwrap();
        core.start_exchange().unwrap();
        let row = |name: &str| core.table().rows.iter().position(|r| r.name == name).unwrap() as u32;
        let (der1, der2, x1, x2, u) = (row("der(x1)"), row("der(x2)"), row("x1"), row("x2"), row("u"));
        let unknowns = [der1, der2];
        let columns = |core: &mut Core<Swing>| {
            let mut out = [[0.0; 2]; 2];
            for (column, known) in out.iter_mut().zip([x1, x2]) {
                assert_eq!(core.try_directional_derivative(&unknowns, &[known], &[1.0], column, Mode::ContinuousTime), Some(true));
                assert!(core.jacobians.solver_block_current, "answered from the solver's block");
            }
            out
        };
        // The request is checked by the general path first, as the C function's first call is.
        let mut out = [0.0; 2];
        core.directional_derivative(&unknowns, &[x1], &[1.0], &mut out, Mode::ContinuousTime, "test").unwrap();
        assert_eq!(out, [0.0, -1.0]);
        core.set_continuous_states(&[1.0, 0.25]).unwrap();
        assert_eq!(columns(&mut core), [[0.0, -1.0], [0.5, 0.0]]);
        // The input's column by the general path: d der(x)/du = [x2, -k x1].
        core.directional_derivative(&unknowns, &[u], &[1.0], &mut out, Mode::ContinuousTime, "test").unwrap();
        assert_eq!(out, [0.25, -2.0]);
        let version = core.version;
        core.set_continuous_states(&[2.0, 0.75]).unwrap();
        assert_eq!(core.version, version, "a new point at the same version: the same kept lift and field values");
        assert_eq!(columns(&mut core), [[0.0, -1.0], [0.5, 0.0]]);
    }

    /// A driven input moves inside a Co-Simulation step without a set (the version stays):
    /// the implicit solver's block after a step must take the input's value at the step's end,
    /// in Step Mode and in (FMI 3.0's) Event Mode alike, while the field values read at an
    /// unchanged version serve only when no input is driven. u = 0.5 + t (u' = 1), k = 2: d
    /// der(x)/dx = -k u = -1 at t = 0, -2 at t = 0.5, -3 at t = 1, exactly.
    #[test]
    fn the_solver_block_follows_a_driven_input_through_a_step() {
        let mut core = Core::<Scaled>::new("scaled", Logger::new(None, false), NAMES);
        core.setup(Some(1e-10), 0.0, None).unwrap();
        core.start().unwrap();
        let row = |name: &str| core.table().rows.iter().position(|r| r.name == name).unwrap() as u32;
        let (der, x, u) = (row("der(x)"), row("x"), row("u"));
        core.set_input_derivatives(&[u], &[1], &[1.0], "test").unwrap();
        let column = |core: &mut Core<Scaled>, mode: Mode| {
            let mut out = [0.0];
            if core.jacobians.asked != [der] || core.jacobians.mode != Some(mode) {
                core.directional_derivative(&[der], &[x], &[1.0], &mut out, mode, "test").unwrap();
            }
            assert_eq!(core.try_directional_derivative(&[der], &[x], &[1.0], &mut out, mode), Some(true));
            assert!(core.jacobians.solver_block_current, "answered from the solver's block");
            out[0]
        };
        for mode in [Mode::Step, Mode::Event] {
            let t = core.time();
            let before = column(&mut core, mode);
            let version = core.version;
            core.do_step(t, 0.5).unwrap();
            assert_eq!(core.version, version, "the step set nothing: only the driven input moved");
            let after = column(&mut core, mode);
            assert_eq!((before, after), (-2.0 * (0.5 + t), -2.0 * (1.0 + t)), "{}", mode.name());
        }
    }

    /// x' = -c x with c = 1 until x falls through 1, then 3 (latched at the event): an event
    /// changes the equations' regime without moving time or states.
    #[derive(Debug, Clone, Serialize, Deserialize, Variables)]
    #[variables(states = S)]
    struct Latch<T = f64> {
        /// Rate constant before the event
        #[parameter]
        c: T,
        /// The event has fired
        #[output]
        latched: bool,
    }

    impl Default for Latch {
        fn default() -> Self {
            Latch { c: 1.0, latched: false }
        }
    }

    impl<T: Scalar> Equations<T> for Latch<T> {
        fn initial_state(&mut self, x: &mut [T]) -> Result<(), ModelError> {
            S { x: T::from(2.0) }.store(x);
            Ok(())
        }

        fn derivatives(&self, _t: T, x: &[T], dx: &mut [T]) {
            let S { x } = S::load(x);
            let c = if self.latched { self.c * T::from(3.0) } else { self.c };
            S { x: -c * x }.store(dx);
        }
    }

    impl Model for Latch {
        const N_STATES: usize = 1;
        const N_EVENT_INDICATORS: usize = 1;

        fn info() -> ModelInfo {
            ModelInfo { identifier: "latch", description: "", stop_time: 1.0, tolerance: 1e-6, output_interval: 0.1, documentation: "" }
        }

        fn event_indicators(&self, _t: f64, x: &[f64], z: &mut [f64]) {
            z[0] = x[0] - 1.0;
        }

        fn on_event(&mut self, _t: f64, _x: &mut [f64], fired: &[bool]) -> Result<EventOutcome, ModelError> {
            self.latched |= fired[0];
            Ok(EventOutcome::Continue)
        }
    }

    /// An event between two of the implicit solver's Jacobians at the same time and states
    /// gives the new regime's: d der(x)/dx = -1 before, -3 after (a stale block would repeat
    /// -1). Continuous-Time Mode on both sides, so only the event tells the blocks apart.
    #[test]
    fn the_solver_block_follows_an_event_at_the_same_states() {
        let mut core = Core::<Latch>::new("latch", Logger::new(None, false), NAMES);
        core.setup(None, 0.0, None).unwrap();
        core.start_exchange().unwrap();
        let row = |name: &str| core.table().rows.iter().position(|r| r.name == name).unwrap() as u32;
        let (der, x) = (row("der(x)"), row("x"));
        // x fell from 2 through 1: the indicator changed sign since the start.
        core.set_continuous_states(&[0.5]).unwrap();
        let mut out = [0.0];
        core.directional_derivative(&[der], &[x], &[1.0], &mut out, Mode::ContinuousTime, "test").unwrap();
        assert_eq!(out, [-1.0]);
        assert_eq!(solver_column(&mut core, &[der], x), -1.0);
        core.event_update().unwrap();
        core.enter_continuous_time().unwrap();
        assert!(core.state.model.latched, "the event fired");
        assert_eq!(solver_column(&mut core, &[der], x), -3.0);
        let mut states = [0.0];
        core.continuous_states(&mut states, false).unwrap();
        assert_eq!(states, [0.5], "the states did not move");
    }

    /// At initialization the parameters are knowns and the state an unknown: x = x0, so
    /// dx/dx0 = 1, d der(x)/dk = -x0, d y/d x0 = 2 x0.
    #[test]
    fn initialization_derivatives_take_the_parameters_as_knowns() {
        let mut core = Core::<Decay>::new("decay", Logger::new(None, false), NAMES);
        core.setup(None, 0.0, None).unwrap();
        let (der, y, x, k, x0) = (vr(&core, "der(x)"), vr(&core, "y"), vr(&core, "x"), vr(&core, "k"), vr(&core, "x0"));
        let mut out = [0.0; 3];
        core.directional_derivative(&[x, der, y], &[x0], &[1.0], &mut out, Mode::Initialization, "test").unwrap();
        assert_eq!(out, [1.0, -2.0, 6.0]);
        core.directional_derivative(&[x, der, y], &[k], &[1.0], &mut out, Mode::Initialization, "test").unwrap();
        assert_eq!(out, [0.0, -3.0, 0.0]);
        // A parameter set during initialization is what the next derivative sees.
        core.set_real(&[x0], &[4.0], Phase::Initializing, "InitializationMode").unwrap();
        core.directional_derivative(&[der], &[k], &[1.0], &mut out[..1], Mode::Initialization, "test").unwrap();
        assert_eq!(out[0], -4.0);
    }

    /// The unknowns are checked once while the calls repeat them: other unknowns (in another
    /// order, or one outside the mode) are checked and placed again. Values by hand as above.
    #[test]
    fn changed_unknowns_are_checked_and_placed_again() {
        let mut core = continuous();
        let (der, y, x, k) = (vr(&core, "der(x)"), vr(&core, "y"), vr(&core, "x"), vr(&core, "k"));
        let mut out = [0.0; 2];
        core.directional_derivative(&[der, y], &[x], &[1.0], &mut out, Mode::ContinuousTime, "test").unwrap();
        assert_eq!(out, [-2.0, 3.0]);
        core.directional_derivative(&[y, der], &[x], &[1.0], &mut out, Mode::ContinuousTime, "test").unwrap();
        assert_eq!(out, [3.0, -2.0]);
        let err = core.directional_derivative(&[y, k], &[x], &[1.0], &mut out, Mode::ContinuousTime, "test").unwrap_err();
        assert!(err.message.contains("'k'") && err.message.contains("is not an unknown"), "{}", err.message);
        core.directional_derivative(&[y, der], &[x], &[1.0], &mut out, Mode::ContinuousTime, "test").unwrap();
        assert_eq!(out, [3.0, -2.0]);
    }

    /// Outside what the mode allows, the call is refused naming the variable and the rule.
    #[test]
    fn unknowns_and_knowns_outside_the_mode_are_refused_by_name() {
        let mut core = continuous();
        let (der, x, k) = (vr(&core, "der(x)"), vr(&core, "x"), vr(&core, "k"));
        let mut out = [0.0; 1];
        let err = core.directional_derivative(&[der], &[k], &[1.0], &mut out, Mode::ContinuousTime, "fmiTest").unwrap_err();
        assert!(
            err.message.contains("'k' (value reference") && err.message.contains("is not a known in Continuous-Time Mode"),
            "{}",
            err.message
        );
        let err = core.directional_derivative(&[x], &[der], &[1.0], &mut out, Mode::ContinuousTime, "fmiTest").unwrap_err();
        assert!(err.message.contains("'der(x)'") && err.message.contains("is not a known"), "{}", err.message);
        let err = core.directional_derivative(&[k], &[x], &[1.0], &mut out, Mode::ContinuousTime, "fmiTest").unwrap_err();
        assert!(err.message.contains("'k'") && err.message.contains("is not an unknown"), "{}", err.message);
        // A state is an output too (the table exposes it so): its derivative is the identity.
        core.directional_derivative(&[x], &[x], &[1.0], &mut out, Mode::ContinuousTime, "fmiTest").unwrap();
        assert_eq!(out[0], 1.0);
        let err = core.directional_derivative(&[der], &[99], &[1.0], &mut out, Mode::ContinuousTime, "fmiTest").unwrap_err();
        assert!(err.message.contains("value reference 99 is not a variable"), "{}", err.message);
        let err = core.directional_derivative(&[der], &[x], &[1.0, 2.0], &mut out, Mode::ContinuousTime, "fmiTest").unwrap_err();
        assert!(err.message.contains("2 seed values for 1 knowns"), "{}", err.message);
        assert!(!err.broken);
    }

    /// A started Co-Simulation instance at t = 0, x = x0 = 3 (k = 2, u = 0.5).
    fn stepping() -> Core<Decay> {
        let mut core = Core::<Decay>::new("decay", Logger::new(None, false), NAMES);
        core.setup(Some(1e-12), 0.0, None).unwrap();
        core.start().unwrap();
        core
    }

    /// The output derivatives against those by hand along x' = -k x + u, y = x^2 + u:
    /// x'' = -k x' + u', x''' = -k x'' + u''; y' = 2 x x' + u', y'' = 2 x'^2 + 2 x x'' + u'',
    /// y''' = 6 x' x'' + 2 x x''' + u'''. At x = 3, u = 0.5 with u' = 0.25, u'' = 0.5,
    /// u''' = -1: x' = -5.5, x'' = 11.25, x''' = -22, y' = -32.75, y'' = 128.5,
    /// y''' = -504.25, all exact in binary, as are the dual numbers' sums and products of them:
    /// equal to the bit. Held inputs (no derivatives set) drop the u terms.
    #[test]
    fn output_derivatives_are_those_by_hand_along_the_trajectory() {
        let mut core = stepping();
        let (x, y, u) = (vr(&core, "x"), vr(&core, "y"), vr(&core, "u"));
        let mut out = [0.0; 6];
        core.output_derivatives(&[x, x, x, y, y, y], &[1, 2, 3, 1, 2, 3], &mut out, "test").unwrap();
        // Held: x'' = 11, x''' = -22, y' = -33, y'' = 2 * 30.25 + 66, y''' = 6 * -5.5 * 11 - 132.
        assert_eq!(out, [-5.5, 11.0, -22.0, -33.0, 126.5, -495.0]);
        core.set_input_derivatives(&[u, u, u], &[1, 2, 3], &[0.25, 0.5, -1.0], "test").unwrap();
        core.output_derivatives(&[x, x, x, y, y, y], &[1, 2, 3, 1, 2, 3], &mut out, "test").unwrap();
        assert_eq!(out, [-5.5, 11.25, -22.0, -32.75, 128.5, -504.25]);
        // Orders outside 1..=3, and variables that are not outputs, are refused by name.
        let err = core.output_derivatives(&[y], &[4], &mut out[..1], "fmiTest").unwrap_err();
        assert!(err.message.contains("order 4 of 'y' refused") && err.message.contains("1 to 3"), "{}", err.message);
        let err = core.output_derivatives(&[u], &[1], &mut out[..1], "fmiTest").unwrap_err();
        assert!(err.message.contains("'u' (value reference") && err.message.contains("not a Real output"), "{}", err.message);
        // The instance keeps the last request's plan: a new request, and the refused one again
        // after a valid one, are checked afresh.
        core.output_derivatives(&[y, x], &[2, 1], &mut out[..2], "test").unwrap();
        assert_eq!(out[..2], [128.5, -5.5]);
        assert!(core.output_derivatives(&[u], &[1], &mut out[..1], "fmiTest").is_err());
    }

    /// The lifted model an instance keeps from one output-derivative call to the next gives
    /// what a fresh lift gives, to the bit: when a step moved a driven input's value (no set in
    /// between, so the kept model is used), and after a held input is set (x' = -k x + u with
    /// u = 1.5 at x = 3: x' = -4.5, x'' = 9, x''' = -18, y' = 2 x x' = -27,
    /// y'' = 2 x'^2 + 2 x x'' = 94.5, y''' = 6 x' x'' + 2 x x''' = -351, exact in binary).
    #[test]
    fn the_kept_lifted_model_gives_what_a_fresh_lift_gives() {
        let fresh = |core: &Core<Decay>| {
            let kept = &core.trajectory;
            let mut pass = super::Trajectory {
                t: core.state.t,
                version: core.version,
                inputs: kept.inputs.clone(),
                outputs: kept.outputs.clone(),
                reads_fields: kept.reads_fields,
                order: kept.order,
                ..Default::default()
            };
            super::trajectory(&mut core.state.model.clone(), &core.state.x, &mut pass).unwrap();
            pass.rates
        };
        let mut core = stepping();
        let (x, y, u) = (vr(&core, "x"), vr(&core, "y"), vr(&core, "u"));
        let (vrs, orders, mut out) = ([x, x, x, y, y, y], [1, 2, 3, 1, 2, 3], [0.0; 6]);
        core.output_derivatives(&vrs, &orders, &mut out, "test").unwrap();
        assert_eq!(out, [-5.5, 11.0, -22.0, -33.0, 126.5, -495.0], "u = 0.5 held");
        core.set_real(&[u], &[1.5], Phase::Running, "StepComplete").unwrap();
        core.output_derivatives(&vrs, &orders, &mut out, "test").unwrap();
        assert_eq!(out, [-4.5, 9.0, -18.0, -27.0, 94.5, -351.0], "u = 1.5 held");
        core.set_input_derivatives(&[u, u, u], &[1, 2, 3], &[0.25, 0.5, -1.0], "test").unwrap();
        core.output_derivatives(&vrs, &orders, &mut out, "test").unwrap();
        let version = core.version;
        core.do_step(0.0, 0.25).unwrap();
        assert_eq!(core.version, version, "a step sets nothing: the kept model is used");
        core.output_derivatives(&vrs, &orders, &mut out, "test").unwrap();
        assert_eq!(core.trajectory.rates, fresh(&core));
        assert_ne!(core.trajectory.inputs[0].1, 1.5, "the driven input moved over the step");
        core.set_real(&[u], &[-2.0], Phase::Running, "StepComplete").unwrap();
        core.output_derivatives(&vrs, &orders, &mut out, "test").unwrap();
        assert_eq!(core.trajectory.rates, fresh(&core));
    }

    /// x' = a cos(x / w) + u a / w, y = a sin(2 pi x / w) / w + x u: parameters in products,
    /// quotients (both ways) and sums with the trajectory's numbers and with each other, under
    /// a sine and a cosine.
    #[derive(Debug, Clone, Serialize, Deserialize, Variables)]
    #[variables(states = S)]
    struct Wave<T = f64> {
        /// Amplitude
        #[parameter]
        a: T,
        /// Wavelength
        #[parameter]
        w: T,
        /// Input
        #[input]
        u: T,
        /// Output
        #[output]
        y: T,
    }

    impl Default for Wave {
        fn default() -> Self {
            Wave { a: 0.3, w: 1.7, u: -0.45, y: 0.0 }
        }
    }

    impl<T: Scalar> Equations<T> for Wave<T> {
        fn initial_state(&mut self, x: &mut [T]) -> Result<(), ModelError> {
            S { x: T::from(0.7) }.store(x);
            Ok(())
        }

        fn derivatives(&self, _t: T, x: &[T], dx: &mut [T]) {
            let S { x } = S::load(x);
            S { x: self.a * (x / self.w).cos() + self.u * self.a / self.w }.store(dx);
        }

        fn outputs(&mut self, _t: T, x: &[T]) {
            let S { x } = S::load(x);
            let k = T::from(2.0 * std::f64::consts::PI) / self.w;
            self.y = self.a * (k * x).sin() / self.w + x * self.u;
        }
    }

    impl Model for Wave {
        const N_STATES: usize = 1;

        fn info() -> ModelInfo {
            ModelInfo { identifier: "wave", description: "", stop_time: 1.0, tolerance: 1e-6, output_interval: 0.1, documentation: "" }
        }
    }

    /// The output derivatives of order 3, in `Taylor3` (whose constants skip num-dual's zero
    /// parts), are those num-dual's `Dual3_64` gives for the same pass, to 16 ulps of the
    /// output's largest; the input held, then driven (u' = 0.25, u'' = -0.5, u''' = 1.5). Not to the bit: a quotient's value
    /// in `Taylor3` is f64's `a / b` where num-dual's is `a * (1 / b)` (see `crate::taylor3`),
    /// which moves the last bit of a value part, here `2 pi / w` and `u a / w`, and of what is
    /// computed from it, which sums with cancellation carry on (6 ulps of the value seen). None
    /// of the numbers is exact in binary, so a term missed would be off by far more.
    #[test]
    fn third_order_output_derivatives_are_num_duals() {
        let mut core = Core::<Wave>::new("wave", Logger::new(None, false), NAMES);
        core.setup(Some(1e-12), 0.0, None).unwrap();
        core.start().unwrap();
        let vr = |core: &Core<Wave>, name: &str| core.table().rows.iter().position(|r| r.name == name).unwrap() as u32;
        let (x, y, u) = (vr(&core, "x"), vr(&core, "y"), vr(&core, "u"));
        for driven in [false, true] {
            if driven {
                core.set_input_derivatives(&[u, u, u], &[1, 2, 3], &[0.25, -0.5, 1.5], "test").unwrap();
            }
            core.do_step(core.time(), 0.125).unwrap();
            let mut out = [0.0; 6];
            core.output_derivatives(&[x, x, x, y, y, y], &[1, 2, 3, 1, 2, 3], &mut out, "test").unwrap();
            assert_eq!(core.trajectory.order, 3);
            let kept = &core.trajectory;
            let mut dual = super::Trajectory {
                t: kept.t,
                version: kept.version,
                inputs: kept.inputs.clone(),
                outputs: kept.outputs.clone(),
                reads_fields: kept.reads_fields,
                order: kept.order,
                ..Default::default()
            };
            super::trajectory_in::<Wave, num_dual::Dual3_64>(&mut core.state.model.clone(), &core.state.x, &mut dual).unwrap();
            for (kept, dual) in core.trajectory.rates.iter().zip(&dual.rates) {
                let scale = dual.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                for (k, d) in kept.iter().zip(dual) {
                    assert!((k - d).abs() <= 16.0 * f64::EPSILON * scale, "driven: {driven}: {kept:?} against {dual:?}");
                }
            }
            assert!(out.iter().all(|v| *v != 0.0 && v.is_finite()), "{out:?}");
        }
    }

    /// Decay whose communication points double k: a model's own communication-point work
    /// changes its fields.
    #[derive(Debug, Clone, Serialize, Deserialize, Variables)]
    #[variables(states = S)]
    struct Doubling<T = f64> {
        /// Rate constant
        #[parameter]
        k: T,
        /// Input
        #[input]
        u: T,
    }

    impl Default for Doubling {
        fn default() -> Self {
            Doubling { k: 2.0, u: 0.5 }
        }
    }

    impl<T: Scalar> Equations<T> for Doubling<T> {
        fn initial_state(&mut self, x: &mut [T]) -> Result<(), ModelError> {
            S { x: T::from(3.0) }.store(x);
            Ok(())
        }

        fn derivatives(&self, _t: T, x: &[T], dx: &mut [T]) {
            let S { x } = S::load(x);
            S { x: -self.k * x + self.u }.store(dx);
        }
    }

    impl Model for Doubling {
        const N_STATES: usize = 1;

        fn info() -> ModelInfo {
            ModelInfo { identifier: "doubling", description: "", stop_time: 1.0, tolerance: 1e-6, output_interval: 0.1, documentation: "" }
        }

        fn communication_point(&mut self, _t: f64, _x: &mut [f64]) -> Result<EventOutcome, ModelError> {
            self.k *= 2.0;
            Ok(EventOutcome::Continue)
        }
    }

    /// The lift kept for output derivatives is dropped when the model's own communication
    /// point may have changed its fields: after a step that doubled k, x' = -k x + u uses the
    /// new k (kept, it would use the old one).
    #[test]
    fn a_communication_point_of_the_model_drops_the_kept_lift() {
        let mut core = Core::<Doubling>::new("doubling", Logger::new(None, false), NAMES);
        core.setup(Some(1e-12), 0.0, None).unwrap();
        core.start().unwrap();
        let x = core.table().rows.iter().position(|r| r.name == "x").unwrap() as u32;
        let mut out = [0.0];
        core.output_derivatives(&[x], &[1], &mut out, "test").unwrap();
        assert_eq!(out, [-2.0 * 3.0 + 0.5]);
        core.do_step(0.0, 0.25).unwrap();
        assert_eq!(core.state.model.k, 4.0);
        core.output_derivatives(&[x], &[1], &mut out, "test").unwrap();
        assert_eq!(out, [-4.0 * core.state.x[0] + 0.5]);
    }

    /// With k = 0, x' = u(t): an input driven by the cubic u(t) = 0.5 + 0.25 t + 0.25 t^2 - t^3 / 6
    /// integrates to x(t) = 3 + 0.5 t + t^2 / 8 + t^3 / 12 - t^4 / 24: the solver (relative
    /// tolerance 1e-10) lands within 1e-11 of it (measured within 1.1e-12). A held input would
    /// give 3 + 0.5 t (off by 0.17 at t = 1). The input's variable follows the polynomial to the end of each step, and
    /// a new value re-anchors it there, its derivatives going on.
    #[test]
    fn a_driven_input_follows_its_polynomial_inside_the_step() {
        let mut core = Core::<Decay>::new("decay", Logger::new(None, false), NAMES);
        core.setup(Some(1e-10), 0.0, None).unwrap();
        let (x, u, k) = (vr(&core, "x"), vr(&core, "u"), vr(&core, "k"));
        core.set_real(&[k], &[0.0], Phase::Initializing, "Instantiated").unwrap();
        core.start().unwrap();
        core.set_input_derivatives(&[u, u, u], &[1, 2, 3], &[0.25, 0.5, -1.0], "test").unwrap();
        let exact = |t: f64| 3.0 + 0.5 * t + t * t / 8.0 + t.powi(3) / 12.0 - t.powi(4) / 24.0;
        let input = |t: f64| 0.5 + 0.25 * t + 0.25 * t * t - t.powi(3) / 6.0;
        let mut v = [0.0; 2];
        for step in 0..2 {
            let t = f64::from(step) * 0.5;
            core.do_step(t, 0.5).unwrap();
            core.get_real(&[x, u], &mut v, Phase::Running).unwrap();
            assert!((v[0] - exact(t + 0.5)).abs() < 1e-11, "x({}) = {} against {}", t + 0.5, v[0], exact(t + 0.5));
            assert!((v[1] - input(t + 0.5)).abs() < 1e-15, "u({}) = {}", t + 0.5, v[1]);
        }
        // A new value at t = 1 moves the polynomial up by 1; its derivatives there are kept.
        core.set_real(&[u], &[input(1.0) + 1.0], Phase::Running, "StepComplete").unwrap();
        core.do_step(1.0, 0.5).unwrap();
        core.get_real(&[x], &mut v[..1], Phase::Running).unwrap();
        assert!((v[0] - (exact(1.5) + 0.5)).abs() < 1e-11, "x(1.5) = {} against {}", v[0], exact(1.5) + 0.5);
        let err = core.set_input_derivatives(&[u], &[0], &[1.0], "fmiTest").unwrap_err();
        assert!(err.message.contains("order 0 of 'u' refused"), "{}", err.message);
        let err = core.set_input_derivatives(&[x], &[1], &[1.0], "fmiTest").unwrap_err();
        assert!(err.message.contains("'x'") && err.message.contains("not a continuous Real input"), "{}", err.message);
    }

    /// A request of lower orders finds the states' derivatives up to its highest order only,
    /// and gives the same numbers as the full request for those orders, to the bit (the
    /// values by hand above: u = 0.5 driven by u' = 0.25, u'' = 0.5, u''' = -1). Decay's
    /// outputs are Real fields: the first-order request runs the Taylor3 pass that also gives
    /// them, stopped at order 1.
    #[test]
    fn lower_orders_are_those_of_the_full_request() {
        let mut core = stepping();
        let (x, y, u) = (vr(&core, "x"), vr(&core, "y"), vr(&core, "u"));
        core.set_input_derivatives(&[u, u, u], &[1, 2, 3], &[0.25, 0.5, -1.0], "test").unwrap();
        let mut out = [0.0; 2];
        core.output_derivatives(&[x, y], &[1, 1], &mut out, "test").unwrap();
        assert_eq!(out, [-5.5, -32.75]);
        assert_eq!(core.trajectory.order, 1);
        assert!(core.trajectory.shares_outputs, "order 1 from the Taylor3 pass that gives the outputs, stopped at order 1");
        core.output_derivatives(&[y, x], &[2, 1], &mut out, "test").unwrap();
        assert_eq!(out, [128.5, -5.5]);
        assert_eq!(core.trajectory.order, 2);
    }

    /// An output derivative that overflows is refused by name, with the value and the time
    /// (fmiError): at x = 1e200, x' = -k x + u = -2e200 is finite but y' = 2 x x' is -inf.
    #[test]
    fn a_non_finite_output_derivative_is_refused_by_name() {
        let mut core = stepping();
        let (x, y) = (vr(&core, "x"), vr(&core, "y"));
        core.state.x[0] = 1e200;
        let mut out = [0.0; 2];
        let err = core.output_derivatives(&[x, y], &[1, 1], &mut out, "fmiTest").unwrap_err();
        assert_eq!(err.status, Status::Error);
        assert!(err.message.contains("fmiTest: the derivative of 'y' is -inf at t = 0 s"), "{}", err.message);
        core.output_derivatives(&[x], &[1], &mut out[..1], "fmiTest").unwrap();
        assert_eq!(out[0], -2e200);
    }

    /// An input's polynomial is found once for its orders in a row: the orders in any order,
    /// or split over calls, give the polynomial of the full request (its output derivatives,
    /// to the bit; u' = 0.25, u'' = 0.5, u''' = -1 as above).
    #[test]
    fn an_inputs_orders_in_any_order_or_calls_are_the_full_request() {
        let rates = |calls: &[(&[i32], &[f64])]| {
            let mut core = stepping();
            let (x, y, u) = (vr(&core, "x"), vr(&core, "y"), vr(&core, "u"));
            for (orders, values) in calls {
                core.set_input_derivatives(&vec![u; orders.len()], orders, values, "test").unwrap();
            }
            let mut out = [0.0; 6];
            core.output_derivatives(&[x, x, x, y, y, y], &[1, 2, 3, 1, 2, 3], &mut out, "test").unwrap();
            out.map(f64::to_bits)
        };
        let full = rates(&[(&[1, 2, 3], &[0.25, 0.5, -1.0])]);
        assert_eq!(rates(&[(&[3, 1, 2], &[-1.0, 0.25, 0.5])]), full);
        assert_eq!(rates(&[(&[2], &[0.5]), (&[3, 1], &[-1.0, 0.25])]), full);
        assert_ne!(rates(&[(&[1, 2], &[0.25, 0.5])]), full, "u''' reaches the output derivatives");
    }

    /// A master sets the same inputs and orders at every step: checked once, but a value that
    /// is not finite is still refused by name, and a different request is checked afresh (a
    /// refused one is not kept: asked again, it is refused again).
    #[test]
    fn a_repeated_input_request_still_refuses_bad_values_and_new_variables() {
        let mut core = stepping();
        let (x, u) = (vr(&core, "x"), vr(&core, "u"));
        core.set_input_derivatives(&[u, u], &[1, 2], &[0.25, 0.5], "test").unwrap();
        core.set_input_derivatives(&[u, u], &[1, 2], &[0.5, 1.0], "test").unwrap();
        let err = core.set_input_derivatives(&[u, u], &[1, 2], &[0.5, f64::NAN], "fmiTest").unwrap_err();
        assert!(err.message.contains("derivative 2 of 'u' = NaN refused"), "{}", err.message);
        for _ in 0..2 {
            let err = core.set_input_derivatives(&[u, x], &[1, 1], &[0.5, 1.0], "fmiTest").unwrap_err();
            assert!(err.message.contains("'x'") && err.message.contains("not a continuous Real input"), "{}", err.message);
        }
        let err = core.set_input_derivatives(&[u, u], &[1, 4], &[0.5, 1.0], "fmiTest").unwrap_err();
        assert!(err.message.contains("order 4 of 'u' refused"), "{}", err.message);
        // The refused calls changed nothing: u' = 0.5, u'' = 1 drive x' = -k x + u.
        let mut rates = [0.0; 2];
        core.output_derivatives(&[x, x], &[1, 2], &mut rates, "test").unwrap();
        assert_eq!(rates, [-5.5, 11.5]);
    }

    /// Derivatives set back to zero leave the input held by the same arithmetic as an input
    /// that never had any: the runs agree to the bit.
    #[test]
    fn zero_derivatives_are_the_hold_bit_for_bit() {
        let run = |set: bool| {
            let mut core = stepping();
            let (x, u) = (vr(&core, "x"), vr(&core, "u"));
            let mut v = [0.0];
            for i in 0..10 {
                let t = f64::from(i) * 0.1;
                core.set_real(&[u], &[0.5 + t], Phase::Running, "StepComplete").unwrap();
                if set {
                    core.set_input_derivatives(&[u, u], &[1, 2], &[1.0, 2.0], "test").unwrap();
                    core.set_input_derivatives(&[u, u], &[1, 2], &[0.0, 0.0], "test").unwrap();
                }
                core.do_step(core.time(), 0.1).unwrap();
            }
            core.get_real(&[x], &mut v, Phase::Running).unwrap();
            v[0].to_bits()
        };
        assert_eq!(run(true), run(false));
    }
}
