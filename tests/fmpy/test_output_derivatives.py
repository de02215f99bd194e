"""Output derivatives and input interpolation through the C boundary, driven by fmpy's own
bindings, against closed forms (independent of the toolkit's dual numbers).

- The road (profile 0, a = 0.04 m, wavelength 3 m, 30 m/s) gives z_r_dot = a w cos(w t),
  w = 2 pi v / wavelength: its first three time derivatives are -a w^2 sin(w t),
  -a w^3 cos(w t) and a w^4 sin(w t). Both FMI versions (fmi2GetRealOutputDerivatives,
  fmi3GetOutputDerivatives) after 13 steps of 1 ms must give them to 1e-12 of each order's scale
  a w^(k+1): the wheel's position is integrated exactly (x' = v), so only the rounding of
  sin and cos at w t = 0.82 rad remains.
- The quarter car on no road of its own (speed 0) integrates its input into z_r. Given
  z_r_dot_ext = 0 with the derivatives 0.3 m/s^2 and -0.6 m/s^3 at t = 0 once
  (fmi2SetRealInputDerivatives), the input is 0.3 t - 0.3 t^2 and z_r = 0.15 t^2 - 0.1 t^3 over
  every later step (to 1e-9: the car's DOPRI5 integrates a quadratic rate exactly but for
  rounding, whatever its tolerance); a held input (what the FMU did before it interpolated)
  leaves z_r at 0."""

import math
import struct

import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave

from conftest import MODELS, fmu_path


def instance(model, version):
    path = fmu_path(model, version)
    md = read_model_description(str(path))
    cls = FMU3Slave if version == "3.0" else FMU2Slave
    slave = cls(guid=md.guid, unzipDirectory=extract(str(path)), modelIdentifier=md.coSimulation.modelIdentifier,
                instanceName=model)
    slave.instantiate()
    return slave, {v.name: v.valueReference for v in md.modelVariables}, md


@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_the_road_rate_derivatives_are_the_closed_form(version):
    slave, vr, md = instance("road", version)
    assert md.coSimulation.maxOutputDerivativeOrder == 3
    if version == "3.0":
        slave.enterInitializationMode(startTime=0)
    else:
        slave.setupExperiment(startTime=0)
        slave.enterInitializationMode()
    slave.exitInitializationMode()
    h, n = 1e-3, 13
    for k in range(n):
        slave.doStep(k * h, h)
    t, a, v = n * h, 0.04, 30.0
    w = 2 * math.pi * v / 3.0
    get = slave.getOutputDerivatives if version == "3.0" else slave.getRealOutputDerivatives
    got = get([vr["z_r_dot"]] * 3, [1, 2, 3])
    want = [-a * w**2 * math.sin(w * t), -a * w**3 * math.cos(w * t), a * w**4 * math.sin(w * t)]
    for k, (g, e) in enumerate(zip(got, want), 1):
        assert abs(g - e) <= 1e-12 * a * w ** (k + 1), (k, g, e)
    slave.terminate()
    slave.freeInstance()


def test_the_car_integrates_its_input_polynomial():
    slave, vr, md = instance("quarter_car", "2.0")
    assert md.coSimulation.canInterpolateInputs
    slave.setupExperiment(startTime=0)
    slave.setReal([vr["speed"]], [0.0])
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    slave.setReal([vr["z_r_dot_ext"]], [0.0])
    slave.setRealInputDerivatives([vr["z_r_dot_ext"]] * 2, [1, 2], [0.3, -0.6])
    h = 0.05
    for k in range(20):
        slave.doStep(k * h, h)
        t = (k + 1) * h
        z_r, rate = slave.getReal([vr["z_r"], vr["z_r_dot_ext"]])
        assert abs(z_r - (0.15 * t**2 - 0.1 * t**3)) <= 1e-9, (t, z_r)
        assert abs(rate - (0.3 * t - 0.3 * t**2)) <= 1e-15, (t, rate)
    slave.terminate()
    slave.freeInstance()


@pytest.mark.parametrize("order", [3, 1])
@pytest.mark.parametrize("model", MODELS)
def test_outputs_read_beside_their_derivatives_are_the_f64_outputs(model, order):
    """A master that reads an FMU's output derivatives at every step gets the outputs themselves
    from the same pass (the toolkit's third-order dual numbers, Taylor3, whose value parts are
    f64's operations), not from a second evaluation in f64: a Jacobi master's orders 1 to 3 and
    a Gauss-Seidel master's first derivative alike (the Taylor3 pass then stops at order 1).
    Every Real variable read that way must be, to the bit, what the FMU gives without the
    derivatives: each model with output derivatives, stepped at its default interval (300 steps,
    or to the end of its experiment or of the run) twice from the same start, once reading every
    Real variable alone and once reading them and then the derivatives of order `order` of every
    continuous output. An input that interpolates gets the same derivatives in both runs, so the
    pass also carries driven inputs. No tolerance: one ulp off anywhere fails."""
    md = read_model_description(str(fmu_path(model, "2.0")))
    if (md.coSimulation.maxOutputDerivativeOrder or 0) < 3:
        pytest.skip(f"{model} gives no output derivatives of order 3")
    reals = [v for v in md.modelVariables if v.type == "Real"]
    everything = [v.valueReference for v in reals]
    outputs = [v.valueReference for v in reals if v.causality == "output" and v.variability == "continuous"]
    inputs = [v.valueReference for v in reals if v.causality == "input" and v.variability == "continuous"]
    h = float(md.defaultExperiment.stepSize)
    steps = min(300, int(round(float(md.defaultExperiment.stopTime) / h)))

    def run(with_derivatives):
        slave, _, _ = instance(model, "2.0")
        slave.setupExperiment(startTime=0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        if inputs and md.coSimulation.canInterpolateInputs:
            slave.setRealInputDerivatives([vr for vr in inputs for _ in range(2)], [1, 2] * len(inputs), [0.3, -0.6] * len(inputs))
        rows = []
        for k in range(steps):
            try:
                slave.doStep(k * h, h)
            except Exception as e:  # a model that ends its experiment early (Discard)
                rows.append(f"ended: {e}")
                break
            rows.append(struct.pack(f"{len(everything)}d", *slave.getReal(everything)))
            if with_derivatives and outputs:
                slave.getRealOutputDerivatives(outputs, [order] * len(outputs))
        slave.terminate()
        slave.freeInstance()
        return rows

    alone, beside = run(False), run(True)
    assert len(alone) == len(beside)
    for k, (a, b) in enumerate(zip(alone, beside)):
        assert a == b, f"{model}: step {k + 1} reads differently beside the output derivatives"
