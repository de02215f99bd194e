//! Benchmark hooks, compiled only with the `bench-hooks` feature (tests/bench/jacobian): one
//! Jacobian as the runner's implicit methods take it through their view of the FMU (the
//! [`System`]), which the importer's public calls do not reach on their own.

use super::Exchange;
use super::{JacobianScratch, ModelExchange, StateStructure, System, Trouble};
use solvers::OdeSystem;

impl<C: Exchange> ModelExchange<C> {
    /// For tests/bench/jacobian only: one Jacobian df/dx at the current time and states `x`
    /// through the integrator's view of the FMU, as the runner's implicit methods take one (n
    /// directional derivatives with unit seeds, or with `directional` false n + 1 derivative
    /// evaluations), into `jacobian` (n x n, row-major), with `work` (3 n values) as scratch.
    /// The FMU is left at the last point evaluated: the next step or linearization sets the
    /// instance's own time and states again, as they always do.
    pub fn bench_solver_jacobian(&mut self, x: &[f64], directional: bool, jacobian: &mut [f64], work: &mut [f64]) -> Result<(), String> {
        let name = self.component.name();
        let n = self.nx;
        if self.integrator.is_none() {
            return Err(format!("{name}: the run was not initialized"));
        }
        if x.len() != n || jacobian.len() != n * n || work.len() != 3 * n {
            return Err(format!("{name}: {} states, a {} matrix and {} work values for {n} states", x.len(), jacobian.len(), work.len()));
        }
        if directional
            && !(self.component.provides_directional_derivative() && self.structure.as_ref().is_some_and(|s| s.states.len() == n))
        {
            return Err(format!("{name}: no directional derivatives of the states' derivatives"));
        }
        if directional && self.bench_groups.len() != n {
            unit_groups(&mut self.bench_groups, n);
        }
        let layout = (self.nz, self.structure.as_ref(), &mut self.jacobian_scratch);
        let columns = (directional, &self.bench_groups[..]);
        let trouble = by_state_count!(n, solver_jacobian::<C>(&self.component, layout, (self.t, x), columns, (jacobian, work)));
        match trouble {
            Some(trouble) => Err(format!("{name}: {}", trouble.message)),
            None => Ok(()),
        }
    }
}

/// One group per state, as the solver's without a sparsity pattern, made once (out of line:
/// in line, its allocation made the differences' path of `solver_jacobian` up to 75
/// instructions dearer per Jacobian).
#[cold]
#[inline(never)]
fn unit_groups(groups: &mut Vec<[usize; 1]>, n: usize) {
    *groups = (0..n).map(|j| [j]).collect();
}

/// One Jacobian df/dx at (`t`, `x`) through a [`System`] of `N` states as the runner's implicit
/// methods take it without a sparsity pattern, into `jacobian` (row-major): the
/// `directional_columns` call the solver's `evaluate_jacobian` makes (`groups`: one per
/// state), or, with `directional` false, n + 1 `rhs` calls (at x, then one forward difference
/// per state). `work` holds 3 n values. What went wrong in the FMU's calls, if anything.
fn solver_jacobian<C: Exchange, const N: usize>(
    calls: &C,
    (nz, structure, scratch): (usize, Option<&StateStructure>, &mut JacobianScratch),
    (t, x): (f64, &[f64]),
    (directional, groups): (bool, &[[usize; 1]]),
    (jacobian, work): (&mut [f64], &mut [f64]),
) -> Option<Trouble> {
    let n = x.len();
    let system = System::<C, N>::new(calls, (n, nz), structure, scratch);
    let (f, rest) = work.split_at_mut(n);
    let (xs, fs) = rest.split_at_mut(n);
    if directional {
        system.directional_columns(t, x, groups, (xs, fs), |group, column| {
            for &j in group {
                for i in 0..n {
                    jacobian[i * n + j] = column[i];
                }
            }
        });
    } else {
        system.rhs(t, x, f);
        for j in 0..n {
            xs.copy_from_slice(x);
            xs[j] = x[j] + f64::EPSILON.sqrt() * x[j].abs().max(1.0);
            let increment = xs[j] - x[j];
            system.rhs(t, xs, fs);
            for i in 0..n {
                jacobian[i * n + j] = (fs[i] - f[i]) / increment;
            }
        }
    }
    system.poisoned.into_inner().or(system.last_discard.into_inner())
}
