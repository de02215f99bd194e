"""Every FMI 3.0 call in every reachable state of every FMI 3.0 FMU, for both interfaces,
against the FMI 3.0.2 state tables (Co-Simulation section 4.3, Model Exchange section 3.3)
written out here independently of fmu/export/src/fmi3/state_machine.rs: an allowed call is
never refused for its sequence, a disallowed one returns fmi3Error with a message naming the
call and the state, the functions that do not apply to these FMUs (clocks, Scheduled
Execution, types no variable has, ...) return fmi3Error in every state, and nothing crashes."""

import ctypes
from ctypes import CFUNCTYPE, byref, c_bool, c_char_p, c_double, c_int, c_size_t, c_uint32, c_void_p

import pytest
from fmpy import extract, read_model_description

from conftest import MODELS, fmu_path
from test_bad_inputs import DIVERGE, MAX_STEPS

LOGGER = CFUNCTYPE(None, c_void_p, c_int, c_char_p, c_char_p)

I, INIT, EVENT, STEP, CT, TERM, ERR = (
    "Instantiated", "Initialization Mode", "Event Mode", "Step Mode", "Continuous-Time Mode", "Terminated", "Error")
ANY = {I, INIT, EVENT, STEP, CT, TERM, ERR}
READ = {INIT, EVENT, STEP, CT, TERM, ERR}
FMU_STATE = ["fmi3GetFMUState", "fmi3SetFMUState", "fmi3FreeFMUState", "fmi3SerializedFMUStateSize",
             "fmi3SerializeFMUState", "fmi3DeserializeFMUState"]
# The functions both interfaces have, and where the standard allows them.
COMMON = {
    "fmi3SetDebugLogging": ANY,
    "fmi3EnterInitializationMode": {I},
    "fmi3ExitInitializationMode": {INIT},
    "fmi3EnterEventMode": {STEP, CT},
    "fmi3Terminate": {EVENT, STEP, CT},
    "fmi3Reset": ANY,
    "fmi3GetFloat64": READ,
    "fmi3GetInt32": READ,
    "fmi3GetBoolean": READ,
    "fmi3GetString": READ,
    # Continuous-Time Mode: continuous-time inputs only, which are Float64.
    "fmi3SetFloat64": {I, INIT, EVENT, STEP, CT},
    "fmi3SetInt32": {I, INIT, EVENT, STEP},
    "fmi3SetBoolean": {I, INIT, EVENT, STEP},
    "fmi3SetString": {I, INIT, EVENT, STEP},
    "fmi3UpdateDiscreteStates": {EVENT},
    **{name: ANY for name in FMU_STATE},
    # Served by every FMU (their models are written for dual numbers): an empty seed reads
    # nothing, so only the call sequence decides.
    "fmi3GetDirectionalDerivative": READ,
    "fmi3GetAdjointDerivative": READ,
}
# fmi3GetOutputDerivatives: served (exact output derivatives); no value references read nothing.
CO_SIMULATION = {"fmi3EnterStepMode": {EVENT}, "fmi3DoStep": {STEP}, "fmi3GetOutputDerivatives": {STEP, TERM, ERR}}
MODEL_EXCHANGE = {
    "fmi3EnterContinuousTimeMode": {EVENT},
    "fmi3CompletedIntegratorStep": {CT},
    "fmi3SetTime": {CT},
    "fmi3SetContinuousStates": {CT},
    "fmi3GetContinuousStateDerivatives": {INIT, EVENT, CT, TERM, ERR},
    "fmi3GetEventIndicators": {INIT, EVENT, CT, TERM, ERR},
    "fmi3GetContinuousStates": {INIT, EVENT, CT, TERM, ERR},
    "fmi3GetNominalsOfContinuousStates": {INIT, EVENT, CT, TERM, ERR},
    "fmi3GetNumberOfEventIndicators": ANY,
    "fmi3GetNumberOfContinuousStates": ANY,
}
# What these FMUs do not have: refused with fmi3Error whatever the state.
NEVER = """fmi3GetFloat32 fmi3GetInt8 fmi3GetUInt8 fmi3GetInt16 fmi3GetUInt16 fmi3GetUInt32 fmi3GetInt64
fmi3GetUInt64 fmi3GetBinary fmi3GetClock fmi3SetFloat32 fmi3SetInt8 fmi3SetUInt8 fmi3SetInt16
fmi3SetUInt16 fmi3SetUInt32 fmi3SetInt64 fmi3SetUInt64 fmi3SetBinary fmi3SetClock
fmi3GetNumberOfVariableDependencies fmi3GetVariableDependencies fmi3EnterConfigurationMode fmi3ExitConfigurationMode fmi3GetIntervalDecimal
fmi3GetIntervalFraction fmi3GetShiftDecimal fmi3GetShiftFraction fmi3SetIntervalDecimal fmi3SetIntervalFraction
fmi3SetShiftDecimal fmi3SetShiftFraction fmi3EvaluateDiscreteStates fmi3ActivateModelPartition""".split()


def test_the_tables_cover_the_71_instance_functions():
    names = list(COMMON) + list(CO_SIMULATION) + list(MODEL_EXCHANGE) + NEVER
    # 75 minus fmi3GetVersion, the three instantiations and fmi3FreeInstance (checked by use).
    assert len(names) == len(set(names)) == 70


class Fmu:
    def __init__(self, model, tmp_path):
        self.model = model
        path = fmu_path(model, "3.0")
        self.md = read_model_description(str(path))
        d = extract(str(path), unzipdir=str(tmp_path / model))
        self.lib = ctypes.CDLL(f"{d}/binaries/x86_64-linux/{model}.so")
        self.lib.fmi3InstantiateCoSimulation.restype = c_void_p
        self.lib.fmi3InstantiateModelExchange.restype = c_void_p
        self.log = []
        self._logger = LOGGER(lambda env, status, cat, msg: self.log.append(msg.decode()))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.float_vr = next(v.valueReference for v in self.md.modelVariables if v.type == "Float64" and v.causality == "output")
        inputs = [v for v in self.md.modelVariables if v.causality == "input" and v.type == "Float64"]
        self.settable = (inputs[0].valueReference, float(inputs[0].start)) if inputs else None
        self.nx = len(self.md.derivatives)
        self.nz = len(self.md.eventIndicators)
        reals = [v.valueReference for v in self.md.modelVariables if v.type == "Float64"]
        self.reals = (c_uint32 * len(reals))(*reals)

    def new(self, interface):
        token = self.md.instantiationToken.encode()
        if interface == "CS":
            # Event Mode used and early return allowed: every Co-Simulation state is reachable.
            c = self.lib.fmi3InstantiateCoSimulation(b"seq", token, b"", c_bool(False), c_bool(False), c_bool(True), c_bool(True),
                                                     None, c_size_t(0), None, self._logger, None)
        else:
            c = self.lib.fmi3InstantiateModelExchange(b"seq", token, b"", c_bool(False), c_bool(False), None, self._logger)
        assert c
        return c_void_p(c)

    def ok(self, status):
        assert status == 0, self.log

    def drive(self, interface, state):
        """A fresh instance of `interface` in `state`, or None where it cannot get there."""
        if (interface == "CS" and state == CT) or (interface == "ME" and state in (STEP, ERR)):
            return None
        if state == ERR and DIVERGE[self.model][3] != "error":
            # The mechanisms and the trebuchet end a diverging run with terminateSimulation (a
            # limit position, a misfire) instead: Error is unreachable this way for them.
            return None
        L = self.lib
        c = self.new(interface)
        if state == I:
            return c
        if state == ERR:
            # Forward Euler far beyond its stability limit diverges (test_bad_inputs.DIVERGE).
            params, fixed_step, h, _ = DIVERGE[self.model]
            self.ok(L.fmi3SetInt32(c, byref(c_uint32(self.vr["solver"])), c_size_t(1), byref(c_int(0)), c_size_t(1)))
            for name, value in {**params, "fixed_step": fixed_step}.items():
                self.ok(L.fmi3SetFloat64(c, byref(c_uint32(self.vr[name])), c_size_t(1), byref(c_double(value)), c_size_t(1)))
        self.ok(L.fmi3EnterInitializationMode(c, c_bool(False), c_double(0), c_double(0), c_bool(False), c_double(0)))
        if state == INIT:
            return c
        self.ok(L.fmi3ExitInitializationMode(c))
        if state == EVENT:
            return c
        flags = [c_bool() for _ in range(5)]
        self.ok(L.fmi3UpdateDiscreteStates(c, *map(byref, flags), byref(c_double())))
        if interface == "ME":
            self.ok(L.fmi3EnterContinuousTimeMode(c))
            if state == CT:
                return c
            self.ok(L.fmi3EnterEventMode(c))
            self.ok(L.fmi3Terminate(c))
            return c
        self.ok(L.fmi3EnterStepMode(c))
        if state == STEP:
            return c
        out = [c_bool(), c_bool(), c_bool()]
        last = c_double()
        if state == TERM:
            self.ok(L.fmi3DoStep(c, c_double(0), c_double(1e-3), c_bool(True), *map(byref, out), byref(last)))
            self.ok(L.fmi3Terminate(c))
            return c
        params, fixed_step, h, _ = DIVERGE[self.model]
        values = (c_double * len(self.reals))()
        t = 0.0
        for _ in range(MAX_STEPS):
            status = L.fmi3DoStep(c, c_double(t), c_double(h), c_bool(True), *map(byref, out), byref(last))
            if status == 0:
                status = L.fmi3GetFloat64(c, self.reals, c_size_t(len(self.reals)), values, c_size_t(len(self.reals)))
            if status == 3:
                # Broken, not merely refused: the Error state names itself.
                self.log.clear()
                L.fmi3EnterStepMode(c)
                assert any("state Error" in m for m in self.log), self.log
                return c
            if status != 0 or out[1].value:
                break
            if out[0].value:
                self.ok(L.fmi3EnterEventMode(c))
                self.ok(L.fmi3UpdateDiscreteStates(c, *map(byref, flags), byref(c_double())))
                self.ok(L.fmi3EnterStepMode(c))
            t = last.value
        L.fmi3FreeInstance(c)
        return None

    def call(self, c, name):
        L = self.lib
        one = c_size_t(1)
        vr = byref(c_uint32(self.float_vr))
        d, b, n = c_double(), c_bool(), c_size_t()
        flags = [c_bool() for _ in range(5)]
        x = (c_double * max(self.nx, 1))()
        z = (c_double * max(self.nz, 1))()
        state = c_void_p()
        if name in FMU_STATE[1:]:
            self.ok(L.fmi3GetFMUState(c, byref(state)))
        size = c_size_t()
        if name == "fmi3DeserializeFMUState":
            self.ok(L.fmi3SerializedFMUStateSize(c, state, byref(size)))
        buffer = (ctypes.c_uint8 * max(size.value, 1))()
        if name == "fmi3DeserializeFMUState":
            self.ok(L.fmi3SerializeFMUState(c, state, buffer, size))
        copy = c_void_p()
        settable = ((byref(c_uint32(self.settable[0])), one, byref(c_double(self.settable[1])), one)
                    if self.settable else (None, c_size_t(0), None, c_size_t(0)))
        args = {
            "fmi3SetDebugLogging": (c, c_bool(False), c_size_t(0), None),
            "fmi3EnterInitializationMode": (c, c_bool(False), c_double(0), c_double(0), c_bool(False), c_double(0)),
            "fmi3ExitInitializationMode": (c,),
            "fmi3EnterEventMode": (c,),
            "fmi3Terminate": (c,),
            "fmi3Reset": (c,),
            "fmi3GetFloat64": (c, vr, one, byref(d), one),
            "fmi3GetInt32": (c, None, c_size_t(0), None, c_size_t(0)),
            "fmi3GetBoolean": (c, None, c_size_t(0), None, c_size_t(0)),
            "fmi3SetFloat64": (c, *settable),
            "fmi3SetInt32": (c, None, c_size_t(0), None, c_size_t(0)),
            "fmi3SetBoolean": (c, None, c_size_t(0), None, c_size_t(0)),
            "fmi3GetString": (c, None, c_size_t(0), None, c_size_t(0)),
            "fmi3SetString": (c, None, c_size_t(0), None, c_size_t(0)),
            "fmi3UpdateDiscreteStates": (c, *map(byref, flags), byref(d)),
            "fmi3GetFMUState": (c, byref(copy)),
            "fmi3SetFMUState": (c, state),
            "fmi3FreeFMUState": (c, byref(state)),
            "fmi3SerializedFMUStateSize": (c, state, byref(size)),
            "fmi3SerializeFMUState": (c, state, buffer, c_size_t(0)),
            "fmi3DeserializeFMUState": (c, buffer, size, byref(copy)),
            "fmi3EnterStepMode": (c,),
            "fmi3DoStep": (c, c_double(0), c_double(1e-3), c_bool(True), byref(flags[0]), byref(flags[1]), byref(flags[2]), byref(d)),
            "fmi3EnterContinuousTimeMode": (c,),
            "fmi3CompletedIntegratorStep": (c, c_bool(True), byref(flags[0]), byref(flags[1])),
            "fmi3SetTime": (c, c_double(0)),
            "fmi3SetContinuousStates": (c, x, c_size_t(self.nx)),
            "fmi3GetContinuousStateDerivatives": (c, x, c_size_t(self.nx)),
            "fmi3GetEventIndicators": (c, z, c_size_t(self.nz)),
            "fmi3GetContinuousStates": (c, x, c_size_t(self.nx)),
            "fmi3GetNominalsOfContinuousStates": (c, x, c_size_t(self.nx)),
            "fmi3GetNumberOfEventIndicators": (c, byref(n)),
            "fmi3GetNumberOfContinuousStates": (c, byref(n)),
            "fmi3GetDirectionalDerivative": (c, None, c_size_t(0), None, c_size_t(0), None, c_size_t(0), None, c_size_t(0)),
            "fmi3GetAdjointDerivative": (c, None, c_size_t(0), None, c_size_t(0), None, c_size_t(0), None, c_size_t(0)),
            "fmi3GetOutputDerivatives": (c, None, c_size_t(0), None, None, c_size_t(0)),
        }.get(name)
        if args is None:
            # The functions that never apply: the pointer arguments are never read.
            args = (c, None, c_size_t(0), None, None, None, None, None, None)
        status = getattr(L, name)(*args)
        for s in (state, copy):
            if s.value:
                L.fmi3FreeFMUState(c, byref(s))
        return status


@pytest.mark.parametrize("model", MODELS)
def test_every_call_in_every_state(model, tmp_path):
    fmu = Fmu(model, tmp_path)
    reached = {"CS": set(), "ME": set()}
    for interface, own, other in (("CS", CO_SIMULATION, MODEL_EXCHANGE), ("ME", MODEL_EXCHANGE, CO_SIMULATION)):
        table = {**COMMON, **own, **{name: set() for name in other}, **{name: set() for name in NEVER}}
        for state in [I, INIT, EVENT, STEP, CT, TERM, ERR]:
            for name, allowed in table.items():
                c = fmu.drive(interface, state)
                if c is None:
                    break
                reached[interface].add(state)
                fmu.log.clear()
                status = fmu.call(c, name)
                sequence_error = any("illegal call sequence" in m for m in fmu.log)
                if name in NEVER:
                    assert status == 3 and any(name in m for m in fmu.log), f"{name} in {state}: {status} {fmu.log}"
                elif state in allowed:
                    assert not sequence_error, f"{interface} {name} refused in {state}: {fmu.log}"
                elif name in other:
                    assert status == 3 and sequence_error and any(name in m and "instantiated for" in m for m in fmu.log), \
                        f"{interface} {name}: {fmu.log}"
                else:
                    assert status == 3, f"{interface} {name} in {state} returned {status}"
                    assert sequence_error and any(name in m and state in m for m in fmu.log), f"{interface} {name} in {state}: {fmu.log}"
                fmu.lib.fmi3FreeInstance(c)
    assert reached["CS"] >= {I, INIT, EVENT, STEP, TERM} and reached["ME"] == {I, INIT, EVENT, CT, TERM}
    if DIVERGE[model][3] == "error":
        assert ERR in reached["CS"], f"{model}: the diverging run did not reach the Error state"


def test_event_mode_calls_need_event_mode_at_instantiation(tmp_path):
    """A Co-Simulation instance made without eventModeUsed goes from initialization straight to
    Step Mode, and refuses fmi3EnterEventMode there."""
    fmu = Fmu("bumper", tmp_path)
    L = fmu.lib
    c = c_void_p(L.fmi3InstantiateCoSimulation(b"plain", fmu.md.instantiationToken.encode(), b"", c_bool(False), c_bool(False),
                                                c_bool(False), c_bool(False), None, c_size_t(0), None, fmu._logger, None))
    fmu.ok(L.fmi3EnterInitializationMode(c, c_bool(False), c_double(0), c_double(0), c_bool(False), c_double(0)))
    fmu.ok(L.fmi3ExitInitializationMode(c))
    assert L.fmi3EnterStepMode(c) == 3 and "Step Mode" in fmu.log[-1]
    assert L.fmi3EnterEventMode(c) == 3 and "eventModeUsed = false" in fmu.log[-1]
    out = [c_bool(), c_bool(), c_bool()]
    fmu.ok(L.fmi3DoStep(c, c_double(0), c_double(1.0), c_bool(True), *map(byref, out), byref(c_double())))
    assert [o.value for o in out] == [False, False, False], "the release is handled inside the step"
    L.fmi3FreeInstance(c)


def test_instantiation_refuses_a_wrong_token_and_scheduled_execution(tmp_path):
    fmu = Fmu("second_order", tmp_path)
    L = fmu.lib
    L.fmi3InstantiateScheduledExecution.restype = c_void_p
    assert not L.fmi3InstantiateCoSimulation(b"x", b"{nope}", b"", c_bool(False), c_bool(False), c_bool(False), c_bool(False),
                                             None, c_size_t(0), None, fmu._logger, None)
    assert "instantiationToken" in fmu.log[-1]
    assert not L.fmi3InstantiateModelExchange(b"", fmu.md.instantiationToken.encode(), b"", c_bool(False), c_bool(False), None, fmu._logger)
    assert "instanceName" in fmu.log[-1]
    assert not L.fmi3InstantiateScheduledExecution(b"x", fmu.md.instantiationToken.encode(), b"", c_bool(False), c_bool(False),
                                                   None, fmu._logger, None, None, None)
    assert "Scheduled Execution" in fmu.log[-1]
    # A state of the other FMI version is not one of these.
    state = c_void_p()
    c = fmu.new("CS")
    fmu.ok(L.fmi3GetFMUState(c, byref(state)))
    size = c_size_t()
    fmu.ok(L.fmi3SerializedFMUStateSize(c, state, byref(size)))
    buffer = (ctypes.c_uint8 * size.value)()
    fmu.ok(L.fmi3SerializeFMUState(c, state, buffer, size))
    buffer[-1] ^= 0xFF
    copy = c_void_p()
    assert L.fmi3DeserializeFMUState(c, buffer, size, byref(copy)) == 3 and "corrupted" in fmu.log[-1]
    L.fmi3FreeFMUState(c, byref(state))
    L.fmi3FreeInstance(c)


@pytest.mark.parametrize("direction", ["ME to CS", "CS to ME"])
def test_an_event_mode_state_of_the_other_interface_is_refused(direction, tmp_path):
    """Event Mode is a state of both FMI 3.0 interfaces, but what an instance holds there is
    not: a Model Exchange instance has no solver of its own, a Co-Simulation one does. A state
    taken in Event Mode by one interface and set into the other is refused, naming why, and
    the instance goes on (found by the ThreadSanitizer fuzzer: a Model Exchange state set into
    a Co-Simulation instance made its next fmi3DoStep fail inside the model code)."""
    fmu = Fmu("second_order", tmp_path)
    L = fmu.lib
    source, target = ("ME", "CS") if direction == "ME to CS" else ("CS", "ME")
    a, b = fmu.drive(source, EVENT), fmu.drive(target, EVENT)
    state = c_void_p()
    fmu.ok(L.fmi3GetFMUState(a, byref(state)))
    assert L.fmi3SetFMUState(b, state) == 3 and "cannot continue" in fmu.log[-1], fmu.log[-3:]
    flags = [c_bool() for _ in range(5)]
    fmu.ok(L.fmi3UpdateDiscreteStates(b, *map(byref, flags), byref(c_double())))
    if target == "CS":
        fmu.ok(L.fmi3EnterStepMode(b))
        out = [c_bool(), c_bool(), c_bool()]
        fmu.ok(L.fmi3DoStep(b, c_double(0), c_double(1e-3), c_bool(True), *map(byref, out), byref(c_double())))
    L.fmi3FreeFMUState(a, byref(state))
    L.fmi3FreeInstance(a)
    L.fmi3FreeInstance(b)
