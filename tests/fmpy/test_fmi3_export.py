"""Every model as an FMI 3.0 FMU (target/fmu3), checked with fmpy as an independent importer:
fmpy's validation, all 75 functions exported, a description that says what the FMI 2.0 one says
(same variables, units, dependencies), Co-Simulation results equal to the FMI 2.0 FMU's bit for
bit when the arithmetic is the same, Event Mode and early return at the located events, FMU
state round trips, and the runner's run of the FMI 3.0 FMU against its run of the FMI 2.0 one.
The physics is checked against the independent references by the reference tests, which run on
both versions (the `fmi_version` fixture)."""

import csv
import ctypes
import subprocess
import zipfile

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

from conftest import MODELS, TARGET, fmu_path

FMI3_FUNCTIONS = """
fmi3GetVersion fmi3SetDebugLogging fmi3InstantiateModelExchange fmi3InstantiateCoSimulation
fmi3InstantiateScheduledExecution fmi3FreeInstance fmi3EnterInitializationMode
fmi3ExitInitializationMode fmi3EnterEventMode fmi3Terminate fmi3Reset fmi3GetFloat32
fmi3GetFloat64 fmi3GetInt8 fmi3GetUInt8 fmi3GetInt16 fmi3GetUInt16 fmi3GetInt32 fmi3GetUInt32
fmi3GetInt64 fmi3GetUInt64 fmi3GetBoolean fmi3GetString fmi3GetBinary fmi3GetClock
fmi3SetFloat32 fmi3SetFloat64 fmi3SetInt8 fmi3SetUInt8 fmi3SetInt16 fmi3SetUInt16 fmi3SetInt32
fmi3SetUInt32 fmi3SetInt64 fmi3SetUInt64 fmi3SetBoolean fmi3SetString fmi3SetBinary fmi3SetClock
fmi3GetNumberOfVariableDependencies fmi3GetVariableDependencies fmi3GetFMUState fmi3SetFMUState
fmi3FreeFMUState fmi3SerializedFMUStateSize fmi3SerializeFMUState fmi3DeserializeFMUState
fmi3GetDirectionalDerivative fmi3GetAdjointDerivative fmi3EnterConfigurationMode
fmi3ExitConfigurationMode fmi3GetIntervalDecimal fmi3GetIntervalFraction fmi3GetShiftDecimal
fmi3GetShiftFraction fmi3SetIntervalDecimal fmi3SetIntervalFraction fmi3SetShiftDecimal
fmi3SetShiftFraction fmi3EvaluateDiscreteStates fmi3UpdateDiscreteStates
fmi3EnterContinuousTimeMode fmi3CompletedIntegratorStep fmi3SetTime fmi3SetContinuousStates
fmi3GetContinuousStateDerivatives fmi3GetEventIndicators fmi3GetContinuousStates
fmi3GetNominalsOfContinuousStates fmi3GetNumberOfEventIndicators fmi3GetNumberOfContinuousStates
fmi3EnterStepMode fmi3GetOutputDerivatives fmi3DoStep fmi3ActivateModelPartition
""".split()

# The models with events: their Event Mode and early-return runs stop inside steps.
HYBRID = ["bumper", "trebuchet", "offset_crank_slider", "double_rocker", "crank_slider", "crank_rocker"]


def test_fmi3_functions_h_has_75_functions():
    assert len(FMI3_FUNCTIONS) == 75 and len(set(FMI3_FUNCTIONS)) == 75


@pytest.fixture(params=MODELS)
def model(request):
    return request.param


def test_fmpy_validation_reports_no_problem(model):
    problems = validate_fmu(str(fmu_path(model, "3.0")))
    assert problems == [], "\n".join(problems)


def test_all_75_functions_are_exported_from_the_x86_64_linux_binary(model, tmp_path):
    path = fmu_path(model, "3.0")
    with zipfile.ZipFile(path) as z:
        names = set(z.namelist())
        # The same binary and the same documentation page as the FMI 2.0 FMU.
        with zipfile.ZipFile(fmu_path(model, "2.0")) as z2:
            assert z.read(f"binaries/x86_64-linux/{model}.so") == z2.read(f"binaries/linux64/{model}.so")
            assert z.read("documentation/index.html") == z2.read("documentation/index.html")
            # The model's resources (road's measured profile): the same files in both.
            resources = {n for n in names if n.startswith("resources/")}
            assert resources == {n for n in z2.namelist() if n.startswith("resources/")}
            assert all(z.read(n) == z2.read(n) for n in resources)
    # Plus the reference result of the default experiment under FMI-LS-REF (FMI 3.0 only).
    ls_ref = {"extra/org.fmi-standard.fmi-ls-ref/fmi-ls-manifest.xml", f"extra/org.fmi-standard.fmi-ls-ref/{model}_out.csv"}
    assert names - resources == {"modelDescription.xml", f"binaries/x86_64-linux/{model}.so", "documentation/index.html", *ls_ref}
    d = extract(str(path), unzipdir=str(tmp_path / "fmu"))
    lib = ctypes.CDLL(f"{d}/binaries/x86_64-linux/{model}.so")
    assert [name for name in FMI3_FUNCTIONS if not hasattr(lib, name)] == []
    lib.fmi3GetVersion.restype = ctypes.c_char_p
    assert lib.fmi3GetVersion() == b"3.0"


def test_description_says_what_the_fmi2_description_says(model):
    md3 = read_model_description(str(fmu_path(model, "3.0")))
    md2 = read_model_description(str(fmu_path(model, "2.0")))
    assert md3.fmiVersion == "3.0" and md3.instantiationToken == md2.guid
    cs, me = md3.coSimulation, md3.modelExchange
    assert cs.modelIdentifier == me.modelIdentifier == model
    assert cs.hasEventMode and cs.mightReturnEarlyFromDoStep and cs.canHandleVariableCommunicationStepSize
    for interface in (cs, me):
        assert interface.canGetAndSetFMUstate and interface.canSerializeFMUstate
    assert me.needsCompletedIntegratorStep
    assert md3.defaultExperiment.stopTime == md2.defaultExperiment.stopTime
    assert md3.defaultExperiment.tolerance == md2.defaultExperiment.tolerance
    assert md3.defaultExperiment.stepSize == md2.defaultExperiment.stepSize
    assert [u.name for u in md3.unitDefinitions] == [u.name for u in md2.unitDefinitions]
    assert [[(d.name, d.factor) for d in u.displayUnits] for u in md3.unitDefinitions] == \
        [[(d.name, d.factor) for d in u.displayUnits] for u in md2.unitDefinitions]
    types = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean", "String": "String"}
    # FMI 3.0 declares units through TypeDefinitions (as the Reference FMUs do), FMI 2.0 on
    # the variable: the unit and display unit a variable ends up with are the same.
    unit = lambda v: (v.unit or getattr(v.declaredType, "unit", None), v.displayUnit or getattr(v.declaredType, "displayUnit", None))
    same = lambda v, t: (v.name, v.valueReference, t, v.causality, v.variability, v.initial, v.start, unit(v))
    n = len(md2.modelVariables)
    assert [same(v, v.type) for v in md3.modelVariables[:n]] == [same(v, types[v.type]) for v in md2.modelVariables]
    assert all(v.unit is None and v.displayUnit is None for v in md3.modelVariables), "no unit on an FMI 3.0 variable"
    # FMI 3.0 names the event indicators as variables, after the table's.
    indicators = md3.modelVariables[n:]
    assert [v.name for v in indicators] == [f"event_indicator_{k}" for k in range(md2.numberOfEventIndicators)]
    assert [u.variable.name for u in md3.eventIndicators] == [v.name for v in indicators]
    # The same ModelStructure, dependency for dependency.
    deps = lambda unknowns: [(u.variable.name, sorted(v.name for v in u.dependencies) if u.dependencies is not None else None)
                             for u in unknowns]
    assert deps(md3.outputs) == deps(md2.outputs)
    assert deps(md3.derivatives) == deps(md2.derivatives)
    assert deps(md3.initialUnknowns) == deps(md2.initialUnknowns)
    assert [d.variable.derivative.name for d in md3.derivatives] == [d.variable.derivative.name for d in md2.derivatives]
    assert [c.name for c in md3.logCategories] == [c.name for c in md2.logCategories]


def test_co_simulation_equals_the_fmi2_fmu_bit_for_bit(model):
    """Without Event Mode and early return the FMI 3.0 step is FMI 2.0's: the same arithmetic."""
    r2 = simulate_fmu(str(fmu_path(model, "2.0")), fmi_type="CoSimulation")
    r3 = simulate_fmu(str(fmu_path(model, "3.0")), fmi_type="CoSimulation")
    if model in ("offset_crank_slider", "double_rocker", "trebuchet"):
        # FMI 2.0 ends with fmi2Discard at lastSuccessfulTime, FMI 3.0 (without early return)
        # with terminateSimulation, which fmpy records at the communication point: the rows
        # before the end are the same.
        r2, r3 = r2[:-1], r3[:-1]
    assert r2.dtype.names == r3.dtype.names and len(r2) == len(r3)
    for name in r2.dtype.names:
        assert np.array_equal(r2[name], r3[name]), name


@pytest.mark.parametrize("hybrid", HYBRID)
def test_event_mode_and_early_return_stop_at_the_located_events(hybrid):
    """With Event Mode and early return the steps stop at each located event, where fmpy's
    Event Mode lets the model handle it; at every communication point the run equals the one
    that handles the events inside the steps, bit for bit: the step after an event goes on from
    it with the same solver state, so the arithmetic is the same (measured: equal)."""
    path = str(fmu_path(hybrid, "3.0"))
    plain = simulate_fmu(path, fmi_type="CoSimulation", relative_tolerance=1e-10)
    stops = simulate_fmu(path, fmi_type="CoSimulation", relative_tolerance=1e-10, use_event_mode=True, early_return_allowed=True)
    dt = float(read_model_description(path).defaultExperiment.stepSize)
    grid = np.abs(stops["time"] / dt - np.round(stops["time"] / dt)) < 1e-9
    off_grid = stops["time"][~grid]
    if hybrid in ("crank_slider", "crank_rocker"):
        assert len(off_grid) == 0, "these linkages turn fully: no event"
    else:
        assert len(off_grid) >= 1, "an event inside a step is recorded at its own time"
    on = stops[grid]
    # Without early return fmpy records the early end (a landing, a limit position) at the next
    # communication point, with early return at its own time: the rows before it are compared.
    n = min(len(on), len(plain))
    assert n >= len(plain) - 1
    for name in plain.dtype.names:
        assert np.array_equal(plain[name][:n], on[name][:n]), name


def test_bumper_events_are_reported_and_handled_in_event_mode(tmp_path):
    """Driven by hand: fmi3DoStep stops at the release with eventHandlingNeeded and
    earlyReturn, lastSuccessfulTime is the release time, fmi3UpdateDiscreteStates lets the model
    separate there, and a step cannot start before it did."""
    path = fmu_path("bumper", "3.0")
    md = read_model_description(str(path))
    d = extract(str(path), unzipdir=str(tmp_path / "b"))
    s = FMU3Slave(guid=md.guid, unzipDirectory=d, modelIdentifier="bumper", instanceName="ev")
    s.instantiate(eventModeUsed=True, earlyReturnAllowed=True)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s.enterInitializationMode(tolerance=1e-10, startTime=0.0)
    s.exitInitializationMode()
    assert s.updateDiscreteStates()[:2] == (False, False)
    s.enterStepMode()
    t, h, events = 0.0, 0.1, []
    while t < 1.0 - 1e-12:
        event, terminate, early, last = s.doStep(t, min(h, 1.0 - t))
        assert not terminate
        if event:
            assert early and t < last < t + h
            assert s.getBoolean([vr["in_contact"]]) == [True], "the model has not handled it yet"
            s.enterEventMode()
            update = s.updateDiscreteStates()
            assert update[0] is False and update[1] is False
            assert s.getBoolean([vr["in_contact"]]) == [False]
            s.enterStepMode()
            events.append(last)
            t = last
        else:
            assert not early and last == pytest.approx(t + min(h, 1.0 - t))
            t = last
    # The release time (test_lab_models: 0.4854844349 s, located to 1e-10 s).
    assert len(events) == 1 and abs(events[0] - 0.4854844349) < 1e-8
    assert s.getFloat64([vr["t_release"]]) == [events[0]]
    s.terminate()
    s.freeInstance()


def _rollback(path, tmp_path, event_mode):
    md = read_model_description(str(path))
    d = extract(str(path), unzipdir=str(tmp_path / ("slave" + str(event_mode))))
    s = FMU3Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier, instanceName="rollback")
    s.instantiate(eventModeUsed=event_mode, earlyReturnAllowed=event_mode)
    s.enterInitializationMode(startTime=0.0)
    s.exitInitializationMode()
    if event_mode:
        s.updateDiscreteStates()
        s.enterStepMode()
    vrs = [v.valueReference for v in md.modelVariables if v.causality == "output" and v.type == "Float64"]
    h = float(md.defaultExperiment.stopTime) / 200

    def run(n):
        rows = []
        for _ in range(n):
            t = s.getFloat64([md.modelVariables[[v.name for v in md.modelVariables].index("time")].valueReference])[0]
            event, terminate, early, last = s.doStep(t, h)
            if terminate:
                break
            if event:
                s.enterEventMode()
                s.updateDiscreteStates()
                s.enterStepMode()
            rows.append(s.getFloat64(vrs) + [last])
        return np.array(rows)

    run(20)
    state = s.getFMUState()
    first = run(20)
    s.setFMUState(state)
    again = run(20)
    blob = s.serializeFMUState(state)
    restored = s.deserializeFMUState(blob)
    s.setFMUState(restored)
    third = run(20)
    s.freeFMUState(state)
    s.freeFMUState(restored)
    s.terminate()
    s.freeInstance()
    return first, again, third


@pytest.mark.parametrize("event_mode", [False, True])
def test_fmu_state_rollback_reproduces_the_run_bit_for_bit(model, tmp_path, event_mode):
    first, again, third = _rollback(fmu_path(model, "3.0"), tmp_path, event_mode)
    assert len(first) > 0
    assert np.array_equal(first, again) and np.array_equal(first, third)


def test_a_state_with_a_pending_event_is_restored_with_it(tmp_path):
    """The FMU state taken where a step stopped at the bumper's release (before Event Mode
    handled it) brings the pending event back: after fmi3SetFMUState, Event Mode handles it
    again, and the serialized copy does the same."""
    path = fmu_path("bumper", "3.0")
    md = read_model_description(str(path))
    d = extract(str(path), unzipdir=str(tmp_path / "b"))
    s = FMU3Slave(guid=md.guid, unzipDirectory=d, modelIdentifier="bumper", instanceName="pending")
    s.instantiate(eventModeUsed=True, earlyReturnAllowed=True)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s.enterInitializationMode(startTime=0.0)
    s.exitInitializationMode()
    s.updateDiscreteStates()
    s.enterStepMode()
    event, _, _, t_event = s.doStep(0.0, 1.0)
    assert event
    state = s.getFMUState()
    blob = s.serializeFMUState(state)
    outcomes = []
    for restore in (lambda: s.setFMUState(state), lambda: s.setFMUState(s.deserializeFMUState(blob))):
        restore()
        s.enterEventMode()
        s.updateDiscreteStates()
        s.enterStepMode()
        s.doStep(t_event, 1.0 - t_event)
        outcomes.append(s.getFloat64([vr["x"], vr["x_mass"], vr["t_release"]]))
    assert outcomes[0] == outcomes[1] and outcomes[0][2] == t_event
    s.terminate()
    s.freeInstance()


RUNNER = TARGET / "release" / "runner"


def _runner_csv(fmu, out, *args):
    p = subprocess.run([str(RUNNER), "simulate", str(fmu), "--out", str(out), *args], capture_output=True, text=True,
                       timeout=600)
    assert p.returncode == 0, p.stderr
    with open(out) as f:
        rows = list(csv.reader(f))
    return rows[0], np.array([[float(x) for x in r] for r in rows[1:]])


def test_the_runner_gives_the_fmi2_numbers_on_the_fmi3_fmu(model, tmp_path):
    """`runner simulate` of the FMI 3.0 FMU writes the FMI 2.0 FMU's CSV bit for bit: the same
    arithmetic, also for the hybrid models, whose steps the runner lets stop at each event (Event
    Mode and early return) and go on from there with the same solver state."""
    h2, r2 = _runner_csv(fmu_path(model, "2.0"), tmp_path / "two.csv")
    h3, r3 = _runner_csv(fmu_path(model, "3.0"), tmp_path / "three.csv")
    assert h2 == h3
    assert np.array_equal(r2, r3)


def test_the_fmi3_road_reads_its_measured_profile_from_the_resource_path(tmp_path):
    """FMI 3.0 hands the FMU its resources folder as a path (FMI 2.0: a file URI): road's
    measured profile (profile 2, resources/profile.csv) gives the FMI 2.0 FMU's CSV bit for bit,
    and is not the default sinusoid (so a profile that was never read would show)."""
    h2, r2 = _runner_csv(fmu_path("road", "2.0"), tmp_path / "two.csv", "--set", "profile=2")
    h3, r3 = _runner_csv(fmu_path("road", "3.0"), tmp_path / "three.csv", "--set", "profile=2")
    _, r0 = _runner_csv(fmu_path("road", "3.0"), tmp_path / "zero.csv")
    assert h2 == h3 and np.array_equal(r2, r3)
    assert not np.array_equal(r3, r0)
