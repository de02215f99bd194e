"""The C boundary as an importer sees it, through fmpy's low-level API with a logger that
records messages: GUID and interface checks, the state machine, refused values, FMU state
serialization checks, reset, debug logging, and concurrent instances."""

import ctypes
import threading

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2Terminated)

from conftest import fmu_path


class Slave:
    """An FMU2Slave whose log messages are kept in `self.log`."""

    def __init__(self, model, tmp_path, guid=None, name="boundary"):
        self.md = read_model_description(str(fmu_path(model)))
        self.dir = extract(str(fmu_path(model)), unzipdir=str(tmp_path / f"{model}-{name}"))
        self.log = []

        def logger(env, instance, status, category, message):
            self.log.append((status, category.decode(), message.decode()))

        self.callbacks = fmi2CallbackFunctions()
        self._logger = fmi2CallbackLoggerTYPE(logger)
        self.callbacks.logger = self._logger
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(lambda n, s: None)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(lambda p: None)
        self.fmu = FMU2Slave(guid=guid or self.md.guid, unzipDirectory=self.dir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=name)

    def vr(self, name):
        return next(v.valueReference for v in self.md.modelVariables if v.name == name)

    def instantiate(self):
        self.fmu.instantiate(callbacks=self.callbacks)
        return self

    def initialize(self):
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()
        return self

    def messages(self):
        return " | ".join(m for _, _, m in self.log)

    def fails(self, call, *args, status=3):
        with pytest.raises(FMICallException) as e:
            call(*args)
        assert e.value.status == status
        return self.log[-1][2]


def test_wrong_guid_is_refused_with_a_reason(tmp_path):
    s = Slave("second_order", tmp_path, guid="{00000000-0000-0000-0000-000000000000}")
    with pytest.raises(Exception, match="Failed to instantiate"):
        s.instantiate()
    assert "GUID" in s.messages() and s.md.guid in s.messages()


def test_an_unknown_fmu_type_is_refused_with_a_reason(tmp_path):
    # fmi2ModelExchange (0) and fmi2CoSimulation (1) both instantiate (test_model_exchange_calls.py).
    s = Slave("second_order", tmp_path)
    comp = s.fmu.fmi2Instantiate(b"other", 7, s.md.guid.encode(), b"", ctypes.byref(s.callbacks), 0, 0)
    assert comp is None
    assert "fmuType = 7 is neither fmi2ModelExchange (0) nor fmi2CoSimulation (1)" in s.messages()


def test_illegal_call_sequences_are_errors_naming_call_and_state(tmp_path):
    s = Slave("second_order", tmp_path).instantiate()
    msg = s.fails(s.fmu.doStep, 0.0, 0.1)
    assert "fmi2DoStep" in msg and "Instantiated" in msg
    msg = s.fails(s.fmu.getReal, [s.vr("q")])
    assert "fmi2GetReal" in msg
    s.initialize()
    msg = s.fails(s.fmu.setupExperiment, None, 0.0)
    assert "StepComplete" in msg
    s.fmu.doStep(0.0, 0.1)
    s.fmu.terminate()
    msg = s.fails(s.fmu.doStep, 0.1, 0.1)
    assert "Terminated" in msg
    # Reading results after terminate is allowed.
    assert np.isfinite(s.fmu.getReal([s.vr("q")])[0])
    s.fmu.freeInstance()


def test_refused_values_name_the_variable(tmp_path):
    s = Slave("mass_spring_damper", tmp_path).instantiate()
    assert "m = nan" in s.fails(s.fmu.setReal, [s.vr("m")], [float("nan")]).lower()
    s.fmu.setReal([s.vr("m")], [-1.0])
    s.fmu.setupExperiment(startTime=0.0)
    s.fmu.enterInitializationMode()
    assert "parameter m" in s.fails(s.fmu.exitInitializationMode)
    s.fmu.freeInstance()

    s = Slave("mass_spring_damper", tmp_path, name="b").instantiate().initialize()
    msg = s.fails(s.fmu.setReal, [s.vr("k")], [100.0])
    assert "'k'" in msg and "fixed" in msg
    assert "output" in s.fails(s.fmu.setReal, [s.vr("x")], [1.0])
    assert "9999" in s.fails(s.fmu.getReal, [9999])
    # The input may change between steps.
    s.fmu.setReal([s.vr("F")], [10.0])
    s.fmu.doStep(0.0, 0.1)
    assert "does not match" in s.fails(s.fmu.doStep, 0.5, 0.1)
    s.fmu.freeInstance()


def test_solver_controls_are_checked_when_set(tmp_path):
    s = Slave("second_order", tmp_path).instantiate()
    assert "solver = 7" in s.fails(s.fmu.setInteger, [s.vr("solver")], [7])
    assert "fixed_step" in s.fails(s.fmu.setReal, [s.vr("fixed_step")], [0.0])
    s.fmu.freeInstance()


def test_serialized_states_are_checked(tmp_path):
    a = Slave("second_order", tmp_path).instantiate().initialize()
    a.fmu.doStep(0.0, 0.5)
    blob = bytes(a.fmu.serializeFMUstate(a.fmu.getFMUstate()))

    corrupted = bytearray(blob)
    corrupted[-3] ^= 0xFF
    assert "corrupted" in a.fails(a.fmu.deSerializeFMUstate, bytes(corrupted))
    assert "bytes" in a.fails(a.fmu.deSerializeFMUstate, blob[:-5])
    assert "not a serialized FMU state" in a.fails(a.fmu.deSerializeFMUstate, b"junk")

    b = Slave("mass_spring_damper", tmp_path).instantiate().initialize()
    assert "another model" in b.fails(b.fmu.deSerializeFMUstate, blob)

    # A good one restores the time and state exactly.
    q = a.fmu.getReal([a.vr("q")])[0]
    a.fmu.doStep(0.5, 0.5)
    a.fmu.setFMUstate(a.fmu.deSerializeFMUstate(blob))
    assert a.fmu.getReal([a.vr("q")])[0] == q
    a.fmu.doStep(0.5, 0.5)


def test_reset_returns_to_start_values_and_reproduces_the_run(tmp_path):
    s = Slave("second_order", tmp_path).instantiate()
    s.fmu.setReal([s.vr("q0")], [5.0])
    s.initialize()
    s.fmu.doStep(0.0, 1.0)
    first = s.fmu.getReal([s.vr("q")])[0]
    s.fmu.reset()
    s.initialize()
    assert s.fmu.getReal([s.vr("q")])[0] == 2.0  # q0's start value, not the 5 set before reset
    s.fmu.reset()
    s.fmu.setReal([s.vr("q0")], [5.0])
    s.initialize()
    s.fmu.doStep(0.0, 1.0)
    assert s.fmu.getReal([s.vr("q")])[0] == first


def test_debug_logging_categories(tmp_path):
    s = Slave("second_order", tmp_path).instantiate()
    s.fmu.setDebugLogging(True, ["logCalls"])
    s.initialize()
    s.fmu.doStep(0.0, 0.1)
    assert any(cat == "logCalls" and "fmi2DoStep" in m for _, cat, m in s.log)
    assert "logNope" in s.fails(s.fmu.setDebugLogging, True, ["logNope"])


def test_discard_at_stop_time_passed(tmp_path):
    s = Slave("second_order", tmp_path).instantiate()
    s.fmu.setupExperiment(startTime=0.0, stopTime=1.0)
    s.fmu.enterInitializationMode()
    s.fmu.exitInitializationMode()
    assert "stop time" in s.fails(s.fmu.doStep, 0.0, 2.0)
    assert not s.fmu.getBooleanStatus(fmi2Terminated)


def _run(model, tmp_path, name, q0):
    s = Slave(model, tmp_path, name=name).instantiate()
    s.fmu.setReal([s.vr("q0")], [q0])
    s.initialize()
    out = []
    for k in range(300):
        s.fmu.doStep(k * 0.01, 0.01)
        out.append(s.fmu.getReal([s.vr("q"), s.vr("q_dot")]))
    s.fmu.terminate()
    s.fmu.freeInstance()
    return np.array(out)


def test_concurrent_instances_match_sequential_runs(tmp_path):
    # ctypes releases the GIL during FMI calls, so these instances really run at once.
    q0s = [0.5, 1.0, 1.5, 2.0]
    sequential = [_run("second_order", tmp_path, f"seq{i}", q0) for i, q0 in enumerate(q0s)]
    results = [None] * len(q0s)

    def work(i):
        results[i] = _run("second_order", tmp_path, f"par{i}", q0s[i])

    threads = [threading.Thread(target=work, args=(i,)) for i in range(len(q0s))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for seq, par in zip(sequential, results):
        assert np.array_equal(seq, par)
