"""Checks every FMU gets, whatever its model: fmpy's validation, the 34 exported functions,
a default Co-Simulation run through fmpy, and a bit-exact get/set/serialize rollback."""

import ctypes
import shutil

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu

FMI2_CS_FUNCTIONS = """
fmi2GetTypesPlatform fmi2GetVersion fmi2SetDebugLogging fmi2Instantiate fmi2FreeInstance
fmi2SetupExperiment fmi2EnterInitializationMode fmi2ExitInitializationMode fmi2Terminate
fmi2Reset fmi2GetReal fmi2GetInteger fmi2GetBoolean fmi2GetString fmi2SetReal
fmi2SetInteger fmi2SetBoolean fmi2SetString fmi2GetFMUstate fmi2SetFMUstate
fmi2FreeFMUstate fmi2SerializedFMUstateSize fmi2SerializeFMUstate fmi2DeSerializeFMUstate
fmi2GetDirectionalDerivative fmi2SetRealInputDerivatives fmi2GetRealOutputDerivatives
fmi2DoStep fmi2CancelStep fmi2GetStatus fmi2GetRealStatus fmi2GetIntegerStatus
fmi2GetBooleanStatus fmi2GetStringStatus
""".split()


def test_the_standard_names_34_functions():
    assert len(FMI2_CS_FUNCTIONS) == 34 and len(set(FMI2_CS_FUNCTIONS)) == 34


def test_fmpy_validation_reports_no_problem(any_fmu):
    problems = validate_fmu(str(any_fmu))
    assert problems == [], "\n".join(problems)


def test_all_34_functions_are_exported(any_fmu, tmp_path):
    md = read_model_description(str(any_fmu))
    unzipdir = extract(str(any_fmu), unzipdir=str(tmp_path / "fmu"))
    lib = ctypes.CDLL(f"{unzipdir}/binaries/linux64/{md.coSimulation.modelIdentifier}.so")
    missing = [name for name in FMI2_CS_FUNCTIONS if not hasattr(lib, name)]
    assert missing == []


def test_description_declares_what_we_promise(any_fmu):
    md = read_model_description(str(any_fmu))
    cs = md.coSimulation
    assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate
    assert cs.canHandleVariableCommunicationStepSize
    assert not cs.canBeInstantiatedOnlyOncePerProcess
    assert float(md.defaultExperiment.stopTime) > 0
    assert float(md.defaultExperiment.tolerance) == 1e-6
    names = {v.name for v in md.modelVariables}
    for control in ("solver", "fixed_step", "abs_tol", "max_step", "n_steps", "n_rhs"):
        assert control in names
    # Every output is listed in ModelStructure/Outputs, in order.
    outputs = [v for v in md.modelVariables if v.causality == "output"]
    assert [u.variable for u in md.outputs] == outputs


def test_default_run_through_fmpy_is_finite(any_fmu):
    md = read_model_description(str(any_fmu))
    result = simulate_fmu(str(any_fmu), fmi_type="CoSimulation")
    assert result["time"][-1] == pytest.approx(float(md.defaultExperiment.stopTime)) or result["time"][-1] > 0
    for name in result.dtype.names:
        assert np.all(np.isfinite(result[name].astype(float))), name


def _slave(fmu_path, tmp_path, name="slave"):
    md = read_model_description(str(fmu_path))
    unzipdir = extract(str(fmu_path), unzipdir=str(tmp_path / name))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    vrs = [v.valueReference for v in md.modelVariables if v.causality == "output" and v.type == "Real"]
    return md, slave, vrs


def _run(slave, vrs, t0, n, h):
    rows = []
    t = t0
    for _ in range(n):
        slave.doStep(currentCommunicationPoint=t, communicationStepSize=h)
        t += h
        rows.append(slave.getReal(vrs))
    return np.array(rows), t


def test_rollback_reproduces_the_run_bit_for_bit(any_fmu, tmp_path):
    """A rollback, and a serialized state restored in this and in a fresh instance, continue as
    the run did, bit for bit (every model, default solver: DOPRI5 stepping across points)."""
    md, slave, vrs = _slave(any_fmu, tmp_path)
    h = float(md.defaultExperiment.stopTime) / 200
    _, t = _run(slave, vrs, 0.0, 20, h)
    state = slave.getFMUstate()
    first, _ = _run(slave, vrs, t, 20, h)
    slave.setFMUstate(state)
    again, _ = _run(slave, vrs, t, 20, h)
    assert np.array_equal(first, again)
    # The same through a serialized copy.
    blob = slave.serializeFMUstate(state)
    restored = slave.deSerializeFMUstate(blob)
    slave.setFMUstate(restored)
    third, _ = _run(slave, vrs, t, 20, h)
    assert np.array_equal(first, third)
    # And in a fresh instance (another library load of the same binary): the state carries the
    # adaptive solver's pending step, so the continuation is the same bit for bit.
    _, fresh, _ = _slave(any_fmu, tmp_path, name="fresh")
    copy = fresh.deSerializeFMUstate(blob)
    fresh.setFMUstate(copy)
    fourth, _ = _run(fresh, vrs, t, 20, h)
    assert np.array_equal(first, fourth)
    fresh.freeFMUstate(copy)
    fresh.terminate()
    fresh.freeInstance()
    slave.freeFMUstate(state)
    slave.freeFMUstate(restored)
    slave.terminate()
    slave.freeInstance()
    shutil.rmtree(tmp_path / "slave", ignore_errors=True)
    shutil.rmtree(tmp_path / "fresh", ignore_errors=True)
