"""Every FMI call in every reachable state of every FMU instantiated for Model Exchange,
against the FMI 2.0 Model Exchange state table (section 3.2.3) written out here independently
of fmu/export/src/fmi2/state_machine.rs: allowed calls never fail for sequence reasons,
disallowed ones (the Co-Simulation functions always) return fmi2Error with a message naming the
call, and nothing crashes."""

import ctypes
from ctypes import byref, c_double, c_int, c_size_t, c_uint, c_void_p

import pytest
from fmpy import extract, read_model_description

from conftest import MODELS, fmu_path
from test_call_sequences import LOGGER, Callbacks

I, INIT, EVENT, CT, TERM = "Instantiated", "InitializationMode", "EventMode", "ContinuousTimeMode", "Terminated"
ANY = {I, INIT, EVENT, CT, TERM}
NEVER = set()
ALLOWED = {
    "fmi2SetDebugLogging": ANY,
    "fmi2SetupExperiment": {I},
    "fmi2EnterInitializationMode": {I},
    "fmi2ExitInitializationMode": {INIT},
    "fmi2Terminate": {EVENT, CT},
    "fmi2Reset": ANY,
    "fmi2GetReal": {INIT, EVENT, CT, TERM},
    "fmi2GetInteger": {INIT, EVENT, CT, TERM},
    "fmi2GetBoolean": {INIT, EVENT, CT, TERM},
    "fmi2GetString": {INIT, EVENT, CT, TERM},
    "fmi2SetReal": {I, INIT, EVENT, CT},
    "fmi2SetInteger": {I, INIT, EVENT},
    "fmi2SetBoolean": {I, INIT, EVENT},
    "fmi2SetString": {I, INIT, EVENT},
    "fmi2GetFMUstate": ANY,
    "fmi2GetDirectionalDerivative": {INIT, EVENT, CT, TERM},
    "fmi2EnterEventMode": {EVENT, CT},
    "fmi2NewDiscreteStates": {EVENT},
    "fmi2EnterContinuousTimeMode": {EVENT},
    "fmi2CompletedIntegratorStep": {CT},
    # In Event Mode only for an FMU without continuous states (footnote 8); every model has some.
    "fmi2SetTime": {CT},
    "fmi2SetContinuousStates": {CT},
    # Initialization Mode too since FMI 2.0.1 (tickets 288 and 1277 of the standard).
    "fmi2GetDerivatives": {INIT, EVENT, CT, TERM},
    "fmi2GetEventIndicators": {INIT, EVENT, CT, TERM},
    "fmi2GetContinuousStates": {INIT, EVENT, CT, TERM},
    "fmi2GetNominalsOfContinuousStates": {I, INIT, EVENT, CT, TERM},
    # The Co-Simulation functions, exported by the same binary, are never legal here.
    "fmi2DoStep": NEVER,
    "fmi2GetStatus": NEVER,
    "fmi2GetBooleanStatus": NEVER,
    "fmi2SetRealInputDerivatives": NEVER,
}


class EventInfo(ctypes.Structure):
    _fields_ = [("newDiscreteStatesNeeded", c_int), ("terminateSimulation", c_int), ("nominalsChanged", c_int),
                ("valuesChanged", c_int), ("nextEventTimeDefined", c_int), ("nextEventTime", c_double)]


class Fmu:
    def __init__(self, model, tmp_path):
        self.md = read_model_description(str(fmu_path(model)))
        d = extract(str(fmu_path(model)), unzipdir=str(tmp_path / model))
        self.lib = ctypes.CDLL(f"{d}/binaries/linux64/{self.md.modelExchange.modelIdentifier}.so")
        self.lib.fmi2Instantiate.restype = c_void_p
        self.log = []
        self._logger = LOGGER(lambda env, name, status, cat, msg: self.log.append(msg.decode()))
        self.callbacks = Callbacks(logger=self._logger)
        self.real = next(v.valueReference for v in self.md.modelVariables if v.type == "Real" and v.causality == "output")
        inputs = [v for v in self.md.modelVariables if v.causality == "input" and v.type == "Real"]
        self.settable_real = (inputs[0].valueReference, float(inputs[0].start)) if inputs else None
        self.nx, self.nz = self.md.numberOfContinuousStates, self.md.numberOfEventIndicators

    def drive(self, state):
        """A fresh Model Exchange instance (fmuType 0) in `state`."""
        L = self.lib
        c = c_void_p(L.fmi2Instantiate(b"seq", 0, self.md.guid.encode(), b"", byref(self.callbacks), 0, 0))
        assert c.value
        if state == I:
            return c
        assert L.fmi2SetupExperiment(c, 0, c_double(0), c_double(0), 0, c_double(0)) == 0
        assert L.fmi2EnterInitializationMode(c) == 0
        if state == INIT:
            return c
        assert L.fmi2ExitInitializationMode(c) == 0
        if state == EVENT:
            return c
        info = EventInfo()
        assert L.fmi2NewDiscreteStates(c, byref(info)) == 0 and not info.newDiscreteStatesNeeded
        assert L.fmi2EnterContinuousTimeMode(c) == 0
        if state == CT:
            return c
        assert L.fmi2Terminate(c) == 0
        return c

    def call(self, c, name):
        L, vr = self.lib, byref(c_uint(self.real))
        d, i = c_double(0), c_int(0)
        x = (c_double * max(self.nx, 1))()
        z = (c_double * max(self.nz, 1))()
        state = c_void_p()
        info = EventInfo()
        enter, terminate = c_int(0), c_int(0)
        L.fmi2GetContinuousStates(c, x, c_size_t(self.nx))  # the current states, to set them back
        args = {
            "fmi2SetDebugLogging": (c, 0, c_size_t(0), None),
            "fmi2SetupExperiment": (c, 0, c_double(0), c_double(0), 0, c_double(0)),
            "fmi2EnterInitializationMode": (c,),
            "fmi2ExitInitializationMode": (c,),
            "fmi2Terminate": (c,),
            "fmi2Reset": (c,),
            "fmi2GetReal": (c, vr, c_size_t(1), byref(d)),
            "fmi2GetInteger": (c, None, c_size_t(0), None),
            "fmi2GetBoolean": (c, None, c_size_t(0), None),
            "fmi2GetString": (c, None, c_size_t(0), None),
            "fmi2SetReal": (c, byref(c_uint(self.settable_real[0])), c_size_t(1), byref(c_double(self.settable_real[1])))
            if self.settable_real else (c, None, c_size_t(0), None),
            "fmi2SetInteger": (c, None, c_size_t(0), None),
            "fmi2SetBoolean": (c, None, c_size_t(0), None),
            "fmi2SetString": (c, None, c_size_t(0), None),
            "fmi2GetFMUstate": (c, byref(state)),
            "fmi2GetDirectionalDerivative": (c, None, c_size_t(0), None, c_size_t(0), None, None),
            "fmi2EnterEventMode": (c,),
            "fmi2NewDiscreteStates": (c, byref(info)),
            "fmi2EnterContinuousTimeMode": (c,),
            "fmi2CompletedIntegratorStep": (c, 1, byref(enter), byref(terminate)),
            "fmi2SetTime": (c, c_double(0.0)),
            "fmi2SetContinuousStates": (c, x, c_size_t(self.nx)),
            "fmi2GetDerivatives": (c, x, c_size_t(self.nx)),
            "fmi2GetEventIndicators": (c, z, c_size_t(self.nz)),
            "fmi2GetContinuousStates": (c, x, c_size_t(self.nx)),
            "fmi2GetNominalsOfContinuousStates": (c, x, c_size_t(self.nx)),
            "fmi2DoStep": (c, c_double(0), c_double(1e-3), 1),
            "fmi2GetStatus": (c, 0, byref(i)),
            "fmi2GetBooleanStatus": (c, 3, byref(i)),
            "fmi2SetRealInputDerivatives": (c, None, c_size_t(0), None, None),
        }[name]
        self.log.clear()
        status = getattr(L, name)(*args)
        if state.value:
            L.fmi2FreeFMUstate(c, byref(state))
        return status


@pytest.mark.parametrize("model", MODELS)
def test_every_model_exchange_call_in_every_state(model, tmp_path):
    fmu = Fmu(model, tmp_path)
    checked = 0
    for state in [I, INIT, EVENT, CT, TERM]:
        for name, allowed in ALLOWED.items():
            c = fmu.drive(state)
            status = fmu.call(c, name)
            sequence_error = any("illegal call sequence" in m for m in fmu.log)
            if state in allowed:
                assert not sequence_error, f"{name} refused in {state}: {fmu.log}"
            else:
                assert status == 3, f"{name} in {state} returned {status}"
                assert sequence_error and any(name in m for m in fmu.log), f"{name} in {state}: {fmu.log}"
                if allowed is not NEVER:
                    assert any(state in m for m in fmu.log), f"{name} in {state}: {fmu.log}"
            fmu.lib.fmi2FreeInstance(c)
            checked += 1
    assert checked == 5 * len(ALLOWED)


def test_an_instance_of_either_interface_comes_from_one_instantiate(tmp_path):
    """fmuType 0 and 1 both instantiate; anything else is refused with the reason."""
    fmu = Fmu("pendulum", tmp_path)
    for fmu_type in (0, 1):
        c = c_void_p(fmu.lib.fmi2Instantiate(b"either", fmu_type, fmu.md.guid.encode(), b"", byref(fmu.callbacks), 0, 0))
        assert c.value
        fmu.lib.fmi2FreeInstance(c)
    fmu.log.clear()
    assert not fmu.lib.fmi2Instantiate(b"neither", 2, fmu.md.guid.encode(), b"", byref(fmu.callbacks), 0, 0)
    assert any("fmuType = 2 is neither fmi2ModelExchange (0) nor fmi2CoSimulation (1)" in m for m in fmu.log), fmu.log
