//! The linearization of a Model Exchange FMU where it stands (its time and states, its inputs'
//! values): the Jacobians A = df/dx, B = df/du, C = dg/dx, D = dg/du of the derivatives f and
//! the outputs g with respect to the states x and the inputs u. From the FMU's directional
//! derivatives when it provides them (one call per state and input), else from central
//! differences of its own derivatives and outputs (two evaluations per state and input), and
//! saying which. An output that is a state itself has the unit row it is by definition.

use super::{Exchange, ModelExchange, StateStructure};
use crate::trace;
use crate::Reader;

/// Where the Jacobians came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum JacobianSource {
    /// The FMU's `GetDirectionalDerivative`, exact.
    DirectionalDerivatives,
    /// Central differences of the FMU's derivatives and outputs.
    FiniteDifferences,
}

impl JacobianSource {
    /// As the runner prints it and writes it into its JSON.
    pub fn text(self) -> &'static str {
        match self {
            JacobianSource::DirectionalDerivatives => "directional derivatives",
            JacobianSource::FiniteDifferences => "finite differences",
        }
    }
}

/// The inputs and outputs a linearization is taken over, by value reference: continuous Real
/// scalars, which the caller picks and reads.
pub struct Ports<'r> {
    /// The inputs (the columns of B and D).
    pub inputs: &'r [u32],
    /// The inputs' current values, in the same order (restored after differencing).
    pub input_values: &'r [f64],
    /// The outputs (the rows of C and D).
    pub outputs: &'r [u32],
    /// Reads the outputs, in the same order.
    pub reader: &'r mut Reader,
}

/// A dense matrix, row-major in one allocation: `m[i]` is row `i`, `m[i][j]` an entry. One
/// allocation rather than one per row: for a small model, a Jacobian's rows cost as much to
/// allocate and free as the FMU's directional derivatives (tests/bench/jacobian).
#[derive(Debug, Clone, PartialEq)]
pub struct Matrix {
    rows: usize,
    columns: usize,
    values: Vec<f64>,
}

impl Matrix {
    /// `rows` x `columns` zeros.
    pub fn zeros(rows: usize, columns: usize) -> Matrix {
        Matrix { rows, columns, values: vec![0.0; rows * columns] }
    }

    /// The number of rows.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// The number of columns.
    pub fn columns(&self) -> usize {
        self.columns
    }

    /// Sets column `column` to `values`, one per row.
    pub fn set_column(&mut self, column: usize, values: &[f64]) {
        assert!(
            column < self.columns && values.len() == self.rows,
            "a column of {} values in a {}x{} matrix",
            values.len(),
            self.rows,
            self.columns
        );
        for (row, v) in self.values.chunks_exact_mut(self.columns).zip(values) {
            row[column] = *v;
        }
    }

    /// The rows as vectors.
    pub fn to_rows(&self) -> Vec<Vec<f64>> {
        (0..self.rows()).map(|i| self[i].to_vec()).collect()
    }
}

impl std::ops::Index<usize> for Matrix {
    type Output = [f64];
    fn index(&self, row: usize) -> &[f64] {
        &self.values[row * self.columns..][..self.columns]
    }
}

impl std::ops::IndexMut<usize> for Matrix {
    fn index_mut(&mut self, row: usize) -> &mut [f64] {
        &mut self.values[row * self.columns..][..self.columns]
    }
}

/// The linearization: rows are the derivatives (of the states, in ModelStructure order) or the
/// outputs, columns the states or the inputs.
#[derive(Debug, Clone, PartialEq)]
pub struct Jacobians {
    /// The time it was taken at.
    pub time: f64,
    /// The states' value references, in ModelStructure order.
    pub states: Vec<u32>,
    /// The states' values.
    pub x: Vec<f64>,
    pub a: Matrix,
    pub b: Matrix,
    pub c: Matrix,
    pub d: Matrix,
    /// How they were computed.
    pub source: JacobianSource,
}

/// The relative perturbation of central differences: the cube root of the machine epsilon
/// balances the truncation error O(h^2) against rounding O(eps/h), both about 4e-11 relative.
const DIFFERENCE_STEP: f64 = 6.055454452393343e-6;

impl<C: Exchange> ModelExchange<C> {
    /// Linearizes the instance at its current time and states (after initialization, or after
    /// a step) over `ports`: from directional derivatives when `prefer` asks for them and the
    /// FMU provides them, else by central differences. The FMU is left at the time, states
    /// and inputs it had.
    pub fn linearize(&mut self, ports: Ports, prefer: JacobianSource) -> Result<Jacobians, String> {
        // The structure is lent for the call rather than cloned: for a small model a clone's
        // allocations cost as much as the FMU's directional derivatives (tests/bench/jacobian).
        let structure = self.structure.take();
        let result = self.linearize_over(structure.as_ref(), ports, prefer);
        self.structure = structure;
        result
    }

    fn linearize_over(&mut self, structure: Option<&StateStructure>, ports: Ports, prefer: JacobianSource) -> Result<Jacobians, String> {
        if self.integrator.is_none() {
            return Err(format!("{}: the instance is not initialized", self.component.name()));
        }
        let empty = StateStructure::default();
        let structure = match structure {
            Some(s) if s.states.len() == self.nx => s,
            Some(s) => {
                return Err(format!(
                    "{}: the ModelStructure names {} state derivatives but the instance has {} continuous states",
                    self.component.name(),
                    s.states.len(),
                    self.nx
                ))
            }
            None if self.nx == 0 => &empty,
            None => {
                return Err(format!(
                    "{}: the modelDescription does not say which variables are the states (no ModelStructure derivative with a 'derivative' attribute), so the states cannot be named",
                    self.component.name()
                ))
            }
        };
        if ports.inputs.len() != ports.input_values.len() || ports.reader.len() != ports.outputs.len() {
            return Err(format!(
                "{}: the inputs' values or the outputs' reader do not match the inputs and outputs",
                self.component.name()
            ));
        }
        self.place()?;
        let (nx, nu, ny) = (self.nx, ports.inputs.len(), ports.outputs.len());
        let mut jacobians = Jacobians {
            time: self.t,
            states: structure.states.clone(),
            x: self.x.clone(),
            a: Matrix::zeros(nx, nx),
            b: Matrix::zeros(nx, nu),
            c: Matrix::zeros(ny, nx),
            d: Matrix::zeros(ny, nu),
            source: JacobianSource::FiniteDifferences,
        };
        // An output that is a state: its row of C is the unit row, of D zero.
        let state_of: Vec<Option<usize>> = ports.outputs.iter().map(|vr| structure.states.iter().position(|s| s == vr)).collect();
        for (row, state) in state_of.iter().enumerate() {
            if let Some(j) = state {
                jacobians.c[row][*j] = 1.0;
            }
        }
        let directional = prefer == JacobianSource::DirectionalDerivatives && self.component.provides_directional_derivative();
        if directional {
            jacobians.source = JacobianSource::DirectionalDerivatives;
            self.directional_columns(&structure.derivatives, &ports, &state_of, &mut jacobians)?;
        } else {
            self.difference_columns(ports, &state_of, &mut jacobians)?;
        }
        if let Some(integrator) = self.integrator.as_mut() {
            integrator.invalidate();
        }
        Ok(jacobians)
    }

    /// Every column by one directional derivative of the derivatives and the outputs that
    /// are not states, seeded with the one state or input: the states' columns go into A and
    /// C, the inputs' into B and D.
    fn directional_columns(
        &mut self,
        derivatives: &[u32],
        ports: &Ports,
        state_of: &[Option<usize>],
        j: &mut Jacobians,
    ) -> Result<(), String> {
        let nx = self.nx;
        let computed: Vec<usize> = (0..ports.outputs.len()).filter(|&r| state_of[r].is_none()).collect();
        let unknowns: Vec<u32> = derivatives.iter().copied().chain(computed.iter().map(|&r| ports.outputs[r])).collect();
        if unknowns.is_empty() {
            return Ok(());
        }
        let mut column = vec![0.0; unknowns.len()];
        for (k, &known) in j.states.iter().chain(ports.inputs).enumerate() {
            self.directional_column(&unknowns, known, &mut column)?;
            let (f, y) = column.split_at(nx);
            let (upper, lower, c) = if k < nx { (&mut j.a, &mut j.c, k) } else { (&mut j.b, &mut j.d, k - nx) };
            upper.set_column(c, f);
            for (&row, &v) in computed.iter().zip(y) {
                lower[row][c] = v;
            }
        }
        Ok(())
    }

    /// The directional derivative of `unknowns` with respect to `known`, seeded 1, into
    /// `column`; refused when the FMU refuses or returns a value that is not finite.
    fn directional_column(&mut self, unknowns: &[u32], known: u32, column: &mut [f64]) -> Result<(), String> {
        let call = C::NAMES.get_directional_derivative.1;
        trace::enter(C::NAMES.get_directional_derivative.0, self.t);
        let status = self.component.directional_derivative(unknowns, &[known], &[1.0], column);
        self.component.check(call, status)?;
        if let Some(k) = column.iter().position(|v| !v.is_finite()) {
            return Err(format!(
                "{}: {call} of value reference {} with respect to {known} at t = {} returned {}",
                self.component.name(),
                unknowns[k],
                self.t,
                column[k]
            ));
        }
        Ok(())
    }

    /// Every column by central differences: each state and each input moved up and down by
    /// a step relative to its value, the derivatives and outputs evaluated at both.
    fn difference_columns(&mut self, ports: Ports, state_of: &[Option<usize>], j: &mut Jacobians) -> Result<(), String> {
        let (nx, ny) = (self.nx, ports.outputs.len());
        let x0 = self.x.clone();
        let (mut f_up, mut f_down) = (vec![0.0; nx], vec![0.0; nx]);
        let (mut y_up, mut y_down) = (vec![0.0; ny], vec![0.0; ny]);
        for column in 0..nx {
            let (up, down) = steps(x0[column]);
            let mut x = x0.clone();
            x[column] = up;
            self.evaluate_at(&x, ports.reader, &mut f_up, &mut y_up)?;
            x[column] = down;
            self.evaluate_at(&x, ports.reader, &mut f_down, &mut y_down)?;
            let width = up - down;
            for i in 0..nx {
                j.a[i][column] = (f_up[i] - f_down[i]) / width;
            }
            for r in (0..ny).filter(|&r| state_of[r].is_none()) {
                j.c[r][column] = (y_up[r] - y_down[r]) / width;
            }
        }
        self.set_states(&x0)?;
        for (column, (&vr, &u0)) in ports.inputs.iter().zip(ports.input_values).enumerate() {
            let (up, down) = steps(u0);
            self.component.set_reals(&[vr], &[up])?;
            self.evaluate_at(&x0, ports.reader, &mut f_up, &mut y_up)?;
            self.component.set_reals(&[vr], &[down])?;
            self.evaluate_at(&x0, ports.reader, &mut f_down, &mut y_down)?;
            self.component.set_reals(&[vr], &[u0])?;
            let width = up - down;
            for i in 0..nx {
                j.b[i][column] = (f_up[i] - f_down[i]) / width;
            }
            for r in (0..ny).filter(|&r| state_of[r].is_none()) {
                j.d[r][column] = (y_up[r] - y_down[r]) / width;
            }
        }
        Ok(())
    }

    /// Sets the states `x`.
    fn set_states(&mut self, x: &[f64]) -> Result<(), String> {
        if !x.is_empty() {
            trace::enter(C::NAMES.set_continuous_states.0, self.t);
            let status = self.component.set_continuous_states(x);
            self.component.check(C::NAMES.set_continuous_states.1, status)?;
        }
        Ok(())
    }

    /// The derivatives `f` and outputs `y` at the states `x` (and the inputs as set).
    fn evaluate_at(&mut self, x: &[f64], reader: &mut Reader, f: &mut [f64], y: &mut [f64]) -> Result<(), String> {
        self.set_states(x)?;
        let call = C::NAMES.get_derivatives.1;
        if !f.is_empty() {
            trace::enter(C::NAMES.get_derivatives.0, self.t);
            let status = self.component.get_derivatives(f);
            self.component.check(call, status)?;
        }
        if !y.is_empty() {
            self.component.read(reader, y)?;
        }
        if let Some(k) = f.iter().chain(y.iter()).position(|v| !v.is_finite()) {
            return Err(format!(
                "{}: a derivative or output was not finite at t = {} while differencing (value {} of the derivatives then the outputs)",
                self.component.name(),
                self.t,
                k
            ));
        }
        Ok(())
    }
}

/// The perturbed values `value + h` and `value - h`, `h` relative to the value (at least the
/// step itself, for values near zero); the differences divide by the distance between the two
/// values as rounded, not by 2 h.
fn steps(value: f64) -> (f64, f64) {
    let h = DIFFERENCE_STEP * value.abs().max(1.0);
    (value + h, value - h)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The step is the cube root of the machine epsilon, which balances the two errors of a
    /// central difference.
    #[test]
    fn the_difference_step_is_the_cube_root_of_epsilon() {
        assert!((DIFFERENCE_STEP - f64::EPSILON.cbrt()).abs() < 1e-15);
        let (up, down) = steps(1e3);
        assert!(((up - down) / 2.0 - 1e3 * DIFFERENCE_STEP).abs() < 1e-12);
    }
}
