"""A model of one's own, outside this repository: `runner new` makes the crate in a temporary
directory, its own test (the template's closed form) passes, it is edited into a damped
oscillator, `runner build --manifest-path` packs its FMI 2.0 and 3.0 FMUs, `runner validate
--strict` finds nothing, and fmpy runs each FMU (Co-Simulation and Model Exchange) against the
oscillator's closed form.

The crate's builds share this checkout's target directory (CARGO_TARGET_DIR): it pins the
checkout's dependency versions (runner new copies Cargo.lock) and its release profile, so the
toolkit's compiled crates are reused and only the model itself is compiled."""

import math
import os
import subprocess
import tempfile

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu

from conftest import ROOT, TARGET

RUNNER = TARGET / "release" / "runner"

# m x'' + c x' + k x = 0, x(0) = x0, x'(0) = 0: underdamped for the defaults (zeta = 0.1).
OSCILLATOR = r'''#![doc = include_str!("../derivation.md")]
#![deny(unsafe_code)]

use fmu_export::{Equations, Model, ModelError, ModelInfo, Scalar, StateVector, Variables};
use serde::{Deserialize, Serialize};

/// A damped oscillator `m x'' + c x' + k x = 0`.
#[derive(Debug, Clone, Serialize, Deserialize, Variables)]
#[variables(states = State)]
pub struct DampedOscillator<T = f64> {
    /// Mass
    #[parameter(unit = "kg", positive)]
    pub m: T,
    /// Damping coefficient
    #[parameter(unit = "N.s/m", non_negative)]
    pub c: T,
    /// Spring stiffness
    #[parameter(unit = "N/m", positive)]
    pub k: T,
    /// Initial displacement
    #[parameter(unit = "m", finite)]
    pub x0: T,
    /// Acceleration x''
    #[output(unit = "m/s2")]
    pub a: T,
}

/// The state vector.
#[derive(StateVector)]
pub struct State<T = f64> {
    /// Displacement
    #[state(unit = "m")]
    pub x: T,
    /// Velocity
    #[state(unit = "m/s")]
    pub v: T,
}

impl Default for DampedOscillator {
    fn default() -> Self {
        DampedOscillator { m: 1.0, c: 0.4, k: 4.0, x0: 0.1, a: 0.0 }
    }
}

impl<T: Scalar> Equations<T> for DampedOscillator<T> {
    fn initial_state(&mut self, x: &mut [T]) -> Result<(), ModelError> {
        State { x: self.x0, v: T::zero() }.store(x);
        Ok(())
    }

    fn derivatives(&self, _t: T, x: &[T], dx: &mut [T]) {
        let State { x, v } = State::load(x);
        State { x: v, v: -(self.c * v + self.k * x) / self.m }.store(dx);
    }

    fn outputs(&mut self, _t: T, x: &[T]) {
        let State { x, v } = State::load(x);
        self.a = -(self.c * v + self.k * x) / self.m;
    }
}

impl Model for DampedOscillator {
    const N_STATES: usize = State::LEN;

    fn info() -> ModelInfo {
        ModelInfo {
            identifier: "damped_oscillator",
            description: "A damped oscillator m x'' + c x' + k x = 0",
            stop_time: 10.0,
            tolerance: 1e-6,
            output_interval: 0.01,
            documentation: include_str!("../derivation.md"),
        }
    }
}

fmu_export::export_fmu!(DampedOscillator);
'''


def closed_form(t, m=1.0, c=0.4, k=4.0, x0=0.1):
    """Underdamped free response: x = x0 exp(-zeta w t) (cos wd t + zeta w / wd sin wd t)."""
    w = math.sqrt(k / m)
    zeta = c / (2 * math.sqrt(k * m))
    wd = w * math.sqrt(1 - zeta**2)
    return x0 * np.exp(-zeta * w * t) * (np.cos(wd * t) + zeta * w / wd * np.sin(wd * t))


def run(*args, **kwargs):
    done = subprocess.run([str(a) for a in args], capture_output=True, text=True, **kwargs)
    assert done.returncode == 0, f"{args} failed ({done.returncode}):\n{done.stdout}\n{done.stderr}"
    return done.stdout


@pytest.fixture(scope="module")
def own_fmus():
    """The oscillator's two FMUs, built from a crate `runner new` made outside the repository."""
    env = dict(os.environ, CARGO_TARGET_DIR=str(TARGET))
    with tempfile.TemporaryDirectory(prefix="own-model-") as tmp:
        crate = os.path.join(tmp, "damped_oscillator")
        assert not crate.startswith(str(ROOT)), "the crate must live outside the repository"
        out = run(RUNNER, "new", "damped_oscillator", "--path", crate, cwd=tmp)
        assert "created model crate damped_oscillator" in out, out
        for f in ["Cargo.toml", "Cargo.lock", "src/lib.rs", "derivation.md"]:
            assert os.path.isfile(os.path.join(crate, f)), f"runner new wrote no {f}"
        # The template as made: its own test against x = exp(-t / tau) passes.
        tests = subprocess.run(["cargo", "test", "--quiet", "--manifest-path", os.path.join(crate, "Cargo.toml")],
                               capture_output=True, text=True, env=env, cwd=tmp)
        assert tests.returncode == 0, tests.stdout + tests.stderr
        assert "2 passed" in tests.stdout, tests.stdout
        # Edited into a damped oscillator.
        with open(os.path.join(crate, "src", "lib.rs"), "w") as f:
            f.write(OSCILLATOR)
        with open(os.path.join(crate, "derivation.md"), "w") as f:
            f.write("# A damped oscillator\n\n`m x'' + c x' + k x = 0`, x(0) = x0, x'(0) = 0.\n")
        out = run(RUNNER, "build", "--manifest-path", os.path.join(crate, "Cargo.toml"), "--out-dir", os.path.join(tmp, "fmus"),
                  env=env, cwd=tmp)
        fmus = out.split()
        assert fmus == [os.path.join(tmp, "fmus", "fmu", "damped_oscillator.fmu"), os.path.join(tmp, "fmus", "fmu3", "damped_oscillator.fmu")], out
        yield fmus


def test_runner_validate_strict_finds_nothing(own_fmus):
    """Every static check and dynamic probe passes on both FMUs; --strict fails on a warning too."""
    out = run(RUNNER, "validate", *own_fmus, "--strict")
    assert "damped_oscillator" in out, out


@pytest.mark.parametrize("fmi_type", ["CoSimulation", "ModelExchange"])
@pytest.mark.parametrize("which", [0, 1], ids=["fmi2", "fmi3"])
def test_fmpy_runs_it_against_the_closed_form(own_fmus, which, fmi_type):
    """fmpy's run of each FMU and interface against the closed form over 10 s (5 periods, the
    amplitude decays to 14 %): Co-Simulation with the FMU's DOPRI5 at rtol 1e-10, Model Exchange
    with fmpy's CVODE at rtol 1e-10; both global errors stay far below 1e-7 of the 0.1 m
    amplitude, while a wrong coefficient (a 1 % change of c or k) moves x by over 1e-4."""
    path = own_fmus[which]
    md = read_model_description(path)
    assert md.fmiVersion == ["2.0", "3.0"][which]
    assert md.coSimulation.modelIdentifier == md.modelExchange.modelIdentifier == "damped_oscillator"
    result = simulate_fmu(path, fmi_type=fmi_type, stop_time=10.0, output_interval=0.01, relative_tolerance=1e-10,
                          output=["x", "v", "a"])
    t = result["time"]
    assert t[-1] == pytest.approx(10.0)
    error = np.max(np.abs(result["x"] - closed_form(t)))
    assert error < 1e-7, f"max |x - closed form| = {error:.3e}"
    # a = -(c v + k x) / m, the FMU's output against its own states.
    assert np.max(np.abs(result["a"] + 0.4 * result["v"] + 4.0 * result["x"])) < 1e-12
