"""Every FMU's exact directional derivatives seen by an independent importer: fmpy's
getDirectionalDerivative (FMI 2.0) and getDirectionalDerivative / getAdjointDerivative (FMI 3.0)
on the Model Exchange interface.

What is compared:
- the Jacobian of the state derivatives and continuous Real outputs with respect to the states
  and Real inputs, through FMI 2.0 and through FMI 3.0: the same values to the bit (one
  implementation behind both);
- that Jacobian against central differences of the FMU's own derivatives and outputs, read
  through fmpy at moved states and inputs (the bound: see `difference_bound`);
- FMI 3.0's adjoint derivative against seed^T J from the directional ones, to rounding;
- the capability flags in both modelDescriptions.
The points: the start of the default experiment, and the state there moved by a few percent
(a state away from rest, where the nonlinear terms matter)."""

import zipfile
from ctypes import POINTER, c_double
from xml.etree import ElementTree

import numpy as np
import pytest
from fmpy import extract, instantiate_fmu, read_model_description

from conftest import MODELS, fmu_path


class Exchange:
    """One Model Exchange instance of `model`'s FMU of `version` in Continuous-Time Mode, with
    the value references of its states, Real inputs, state derivatives and continuous Real
    outputs."""

    def __init__(self, model, version, tmp_path):
        path = fmu_path(model, version)
        self.version = version
        self.md = read_model_description(path)
        unzipdir = extract(path, unzipdir=tmp_path / f"{model}-{version}")
        self.fmu = instantiate_fmu(unzipdir, self.md, fmi_type="ModelExchange")
        variables = {v.name: v for v in self.md.modelVariables}
        self.derivatives = [u.variable for u in self.md.derivatives]
        self.states = [d.derivative for d in self.derivatives]
        real = ("Real", "Float64")
        self.inputs = [v for v in self.md.modelVariables if v.causality == "input" and v.type in real]
        self.outputs = [
            v for v in self.md.modelVariables
            if v.causality == "output" and v.variability == "continuous" and v.type in real and v not in self.states
        ]
        self.names = {v.valueReference: v.name for v in variables.values()}
        if version == "2.0":
            self.fmu.setupExperiment(startTime=0.0)
            self.fmu.enterInitializationMode()
            self.fmu.exitInitializationMode()
            while self.fmu.newDiscreteStates()[0]:
                pass
        else:
            self.fmu.enterInitializationMode(startTime=0.0)
            self.fmu.exitInitializationMode()
            while self.fmu.updateDiscreteStates()[0]:
                pass
        self.fmu.enterContinuousTimeMode()

    def vrs(self, variables):
        return [v.valueReference for v in variables]

    def states_now(self):
        x = np.zeros(len(self.states))
        self.fmu.getContinuousStates(x.ctypes.data_as(POINTER(c_double)), x.size)
        return x

    def set_states(self, x):
        x = np.ascontiguousarray(x, dtype=float)
        self.fmu.setContinuousStates(x.ctypes.data_as(POINTER(c_double)), x.size)

    def unknowns(self):
        """The state derivatives and the continuous Real outputs at the states last set."""
        dx = np.zeros(len(self.states))
        pointer = dx.ctypes.data_as(POINTER(c_double))
        if self.version == "2.0":
            self.fmu.getDerivatives(pointer, dx.size)
            y = self.fmu.getReal(self.vrs(self.outputs)) if self.outputs else []
        else:
            self.fmu.getContinuousStateDerivatives(pointer, dx.size)
            y = self.fmu.getFloat64(self.vrs(self.outputs)) if self.outputs else []
        return np.array(list(dx) + list(y))

    def set_input(self, variable, value):
        if self.version == "2.0":
            self.fmu.setReal([variable.valueReference], [value])
        else:
            self.fmu.setFloat64([variable.valueReference], [value])

    def get(self, variable):
        if self.version == "2.0":
            return self.fmu.getReal([variable.valueReference])[0]
        return self.fmu.getFloat64([variable.valueReference])[0]

    def jacobian(self):
        """Column by column, one directional derivative per known (the importer's way)."""
        unknowns = self.vrs(self.derivatives + self.outputs)
        columns = [self.fmu.getDirectionalDerivative(unknowns, [vr], [1.0]) for vr in self.vrs(self.states + self.inputs)]
        return np.array(columns).T

    def free(self):
        self.fmu.terminate()
        self.fmu.freeInstance()


def difference_jacobian(fmu, h_scale):
    """Central differences of the FMU's own unknowns, each known moved by h_j = h_scale
    max(|v_j|, 1), and the unknowns' values."""
    x0 = fmu.states_now()
    base = fmu.unknowns()
    columns = []
    for j in range(len(x0)):
        h = h_scale * max(abs(x0[j]), 1.0)
        moved = []
        for sign in (1, -1):
            x = x0.copy()
            x[j] += sign * h
            fmu.set_states(x)
            moved.append(fmu.unknowns())
        columns.append((moved[0] - moved[1]) / (2 * h))
    fmu.set_states(x0)
    for u in fmu.inputs:
        v0 = fmu.get(u)
        h = h_scale * max(abs(v0), 1.0)
        moved = []
        for sign in (1, -1):
            fmu.set_input(u, v0 + sign * h)
            moved.append(fmu.unknowns())
        fmu.set_input(u, v0)
        columns.append((moved[0] - moved[1]) / (2 * h))
    return np.array(columns).T, base, x0


def difference_bound(exact, coarse, fine, values, scales):
    """The bound of |exact - fine|: `fine` is the central difference at h_j = 5e-6 max(|v_j|,
    1), `coarse` at twice that. A central difference errs by its truncation, h^2 f''' / 6
    (four times as much at the coarse step, so |coarse - fine| is three times the fine
    difference's), and its rounding, eps |f_i| / h or eps times the size of the terms of a
    quantity that cancels to near zero (up to 1e2 in these models' SI units: 4e-9 at h = 5e-6).
    Hence |coarse - fine| + 1e-6 (|J| + |f_i| / max(|v_j|, 1)) + 1e-8, as the toolkit's own
    check (fmu_export::harness::check_derivatives) bounds it."""
    return np.abs(coarse - fine) + 1e-6 * (np.abs(exact) + np.abs(values)[:, None] / scales[None, :]) + 1e-8


@pytest.mark.parametrize("model", MODELS)
def test_directional_derivatives_agree_across_versions_and_with_differences(model, tmp_path):
    fmus = {v: Exchange(model, v, tmp_path) for v in ("2.0", "3.0")}
    try:
        x_start = fmus["2.0"].states_now()
        # A state away from the start: every state moved by 3 % of its size (or 0.01).
        x_moved = x_start + 0.03 * np.where(x_start != 0, x_start, 1.0 / 3.0)
        compared = 0
        for x in (x_start, x_moved):
            for f in fmus.values():
                f.set_states(x)
            j2, j3 = fmus["2.0"].jacobian(), fmus["3.0"].jacobian()
            assert np.array_equal(j2, j3), f"{model}: FMI 2.0 and 3.0 differ:\n{j2}\n{j3}"
            fine, values, _ = difference_jacobian(fmus["2.0"], 5e-6)
            coarse, _, _ = difference_jacobian(fmus["2.0"], 1e-5)
            scales = np.array([max(abs(v), 1.0) for v in list(x) + [fmus["2.0"].get(u) for u in fmus["2.0"].inputs]])
            bound = difference_bound(j2, coarse, fine, values, scales)
            # |J| of a loop-closure gap's length where the projection made it zero: no derivative
            # exists at a kink (the toolkit reports 0, the symmetric one); central differences
            # give 0 too, to rounding, so the bound holds there as well.
            worst = np.unravel_index(np.argmax(np.abs(j2 - fine) / bound), j2.shape)
            assert np.all(np.abs(j2 - fine) <= bound), (
                f"{model}: d {fmus['2.0'].names[fmus['2.0'].vrs(fmus['2.0'].derivatives + fmus['2.0'].outputs)[worst[0]]]} "
                f"/ d known {worst[1]} = {j2[worst]} exactly, {fine[worst]} by differences (bound {bound[worst]})"
            )
            compared += np.count_nonzero(j2)
            # FMI 3.0's adjoint: w^T J for a weight on every unknown, as the directional ones give it.
            f3 = fmus["3.0"]
            w = np.linspace(1.0, 2.0, j3.shape[0])
            knowns = f3.vrs(f3.states + f3.inputs)
            # One sensitivity per known (fmpy's default length is that of the unknowns).
            adjoint = np.array(f3.fmu.getAdjointDerivative(f3.vrs(f3.derivatives + f3.outputs), knowns, list(w), nSensitivity=len(knowns)))
            assert np.allclose(adjoint, w @ j3, rtol=1e-13, atol=1e-13 * np.abs(w @ np.abs(j3)).max()), f"{model}: {adjoint} vs {w @ j3}"
        assert compared > 0, f"{model}: every derivative was zero, the comparison proves nothing"
    finally:
        for f in fmus.values():
            f.free()


@pytest.mark.parametrize("model", MODELS)
def test_the_capability_flags_are_declared(model):
    md2 = read_model_description(fmu_path(model, "2.0"))
    assert md2.modelExchange.providesDirectionalDerivative
    assert md2.coSimulation.providesDirectionalDerivative
    # FMI 3.0's attributes read from the XML itself: fmpy keeps only FMI 2.0's singular name.
    with zipfile.ZipFile(fmu_path(model, "3.0")) as z:
        root = ElementTree.fromstring(z.read("modelDescription.xml"))
    for interface in ("ModelExchange", "CoSimulation"):
        element = root.find(interface)
        assert element.get("providesDirectionalDerivatives") == "true", interface
        assert element.get("providesAdjointDerivatives") == "true", interface
