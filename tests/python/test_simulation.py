"""fmurunner.Simulation, stepped from Python, against fmpy's own step-by-step API (FMU2Slave,
FMU3Slave) driving the same FMU binary with the same calls: the values must be the same bits at
the same times (same binary, same inputs, same step sizes, so any difference is the importer's).
Then every misuse the issue lists: each must raise RunnerError with a clear message, never take
the interpreter down."""

import math
import os
import pathlib
import shutil
import tempfile
import time

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave

import fmurunner
from fmurunner_helpers import REFERENCE, faulty_fmu, fmu_path

RunnerError = fmurunner.RunnerError


class FmpySlave:
    """fmpy's step-by-step API set up as the runner sets up a Co-Simulation instance: the
    default experiment's tolerance, start time 0, no stop time; FMI 3.0 with event mode and
    early return when the FMU declares them, events handled as FMI 3.0 prescribes
    (fmi3EnterEventMode, fmi3UpdateDiscreteStates until no update is needed, fmi3EnterStepMode)."""

    def __init__(self, path, start_values=None):
        self.md = read_model_description(str(path))
        self.dir = tempfile.mkdtemp(prefix="fmpy-")
        extract(str(path), unzipdir=self.dir)
        self.vars = {v.name: v for v in self.md.modelVariables}
        cs = self.md.coSimulation
        tolerance = self.md.defaultExperiment.tolerance if self.md.defaultExperiment else None
        tolerance = float(tolerance) if tolerance is not None else None
        self.fmi3 = self.md.fmiVersion == "3.0"
        if self.fmi3:
            self.event_mode = bool(cs.hasEventMode)
            self.fmu = FMU3Slave(guid=self.md.instantiationToken, unzipDirectory=self.dir,
                                 modelIdentifier=cs.modelIdentifier, instanceName="fmpy")
            self.fmu.instantiate(eventModeUsed=self.event_mode, earlyReturnAllowed=bool(cs.mightReturnEarlyFromDoStep))
            self.fmu.enterInitializationMode(tolerance=tolerance, startTime=0.0)
        else:
            self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.dir,
                                 modelIdentifier=cs.modelIdentifier, instanceName="fmpy")
            self.fmu.instantiate()
            self.fmu.setupExperiment(tolerance=tolerance, startTime=0.0)
        for name, value in (start_values or {}).items():
            self.set(name, value)
        if not self.fmi3:
            self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()
        if self.fmi3 and self.event_mode:
            self.handle_event()
        self.time = 0.0

    def handle_event(self):
        while True:
            update, terminate, *_ = self.fmu.updateDiscreteStates()
            assert not terminate
            if not update:
                break
        self.fmu.enterStepMode()

    def set(self, name, value):
        v = self.vars[name]
        vr = [v.valueReference]
        setter = {"Real": "setReal", "Integer": "setInteger", "Boolean": "setBoolean", "String": "setString",
                  "Float64": "setFloat64", "Int32": "setInt32", "UInt64": "setUInt64", "Int8": "setInt8",
                  "Binary": "setBinary", "Enumeration": "setInt64" if self.fmi3 else "setInteger"}[v.type]
        getattr(self.fmu, setter)(vr, [value])

    def get(self, name):
        v = self.vars[name]
        getter = {"Real": "getReal", "Integer": "getInteger", "Boolean": "getBoolean", "String": "getString",
                  "Float64": "getFloat64", "Int32": "getInt32", "UInt64": "getUInt64", "Int8": "getInt8",
                  "Binary": "getBinary", "Enumeration": "getInt64" if self.fmi3 else "getInteger"}[v.type]
        value = getattr(self.fmu, getter)([v.valueReference])[0]
        # fmpy's FMI 2.0 getString gives the C string's bytes.
        return value.decode() if v.type == "String" and isinstance(value, bytes) else value

    def step(self, dt):
        """One doStep from the current time; returns (time reached, complete)."""
        if not self.fmi3:
            self.fmu.doStep(self.time, dt)
            self.time += dt
            return self.time, True
        event, terminate, early, last = self.fmu.doStep(self.time, dt)
        assert not terminate
        end = self.time + dt
        reached = last if early else end
        if event and self.event_mode:
            self.fmu.enterEventMode()
            self.handle_event()
        self.time = reached
        return reached, reached == end

    def close(self):
        self.fmu.terminate()
        self.fmu.freeInstance()
        shutil.rmtree(self.dir, ignore_errors=True)


def same_bits(a, b):
    return a == b or (isinstance(a, float) and math.isnan(a) and math.isnan(b))


def test_quarter_car_steps_as_fmpys_fmu2slave_with_an_input_changed_every_step():
    """1000 steps of 1 ms with the road velocity as input (a sine), z_s and z_u read each step:
    the same doubles as fmpy's FMU2Slave doing the same calls."""
    path = fmu_path("quarter_car")
    theirs = FmpySlave(path, {"speed": 0.0})
    with fmurunner.Simulation(path, start_values={"speed": 0.0}) as sim:
        assert sim.time == 0.0
        for k in range(1000):
            u = 0.2 * math.sin(2 * math.pi * 1.5 * k * 1e-3)
            sim.set("z_r_dot_ext", u)
            theirs.set("z_r_dot_ext", u)
            r = sim.step(1e-3)
            t, _ = theirs.step(1e-3)
            assert (r.time, r.complete, r.events) == (t, True, 0) and sim.time == t
            z_s, z_u = sim.get(["z_s", "z_u"])
            assert (z_s, z_u) == (theirs.get("z_s"), theirs.get("z_u")), k
        # A physical check that the input arrived: the road height is the integral of its velocity.
        assert abs(sim.get("z_r") - 0.2 / (2 * math.pi * 1.5) * (1 - math.cos(2 * math.pi * 1.5))) < 1e-6
    theirs.close()


@pytest.mark.parametrize("fmu", ["fmi2/BouncingBall.fmu", "fmi2/VanDerPol.fmu", "fmi3/VanDerPol.fmu", "fmi3/Dahlquist.fmu",
                                 "fmi3/BouncingBall.fmu"])
def test_reference_fmus_step_as_fmpy_steps_them(fmu):
    """The Reference FMUs at 0.1 s steps for 3 s: every output at every step the same bits as
    fmpy's FMU2Slave/FMU3Slave; FMI 3.0 BouncingBall returns early at each bounce, which both
    report at the same time (step() says complete=False), and the next step goes on from there."""
    path = REFERENCE / fmu
    theirs = FmpySlave(path)
    # fmpy also lists the <Alias> elements of FMI 3.0 BouncingBall (h_ft: a later draft of the
    # standard, not FMI 3.0), which the runner does not read: the outputs both know.
    known = {v["name"] for v in fmurunner.info(path)["variables"]}
    outputs = [v.name for v in theirs.md.modelVariables if v.causality == "output" and v.name in known]
    early = 0
    with fmurunner.Simulation(path) as sim:
        while sim.time < 3.0 - 1e-9:
            r = sim.step(0.1)
            t, complete = theirs.step(0.1)
            assert (r.time, r.complete) == (t, complete)
            early += not r.complete
            got = sim.get(outputs)
            for name, value in zip(outputs, got):
                assert same_bits(float(value), float(theirs.get(name))), (name, r.time)
    theirs.close()
    if fmu == "fmi3/BouncingBall.fmu":
        assert early >= 2, "the ball bounces at least twice in 3 s: two early returns"


def test_fmi3_feedthrough_sets_and_gets_every_type():
    """The FMI 3.0 Feedthrough FMU copies each input to its output: what was set comes back,
    with its Python type, and fmpy reads the same from the same instance state."""
    path = REFERENCE / "fmi3" / "Feedthrough.fmu"
    values = {"Float64_continuous_input": 2.5, "Int32_input": -7, "Int8_input": -128, "UInt64_input": 2**64 - 1,
              "Boolean_input": True, "String_input": "héllo", "Binary_input": b"\x00\xffab", "Enumeration_input": 2}
    with fmurunner.Simulation(path) as sim:
        for name, value in values.items():
            sim.set(name, value)
        sim.step(0.1)
        for name, value in values.items():
            got = sim.get(name.replace("_input", "_output"))
            assert got == value and type(got) is type(value), (name, got)
        # numpy scalars and a Real given as an int are taken as their plain values.
        sim.set("Float64_continuous_input", np.float32(0.5))
        sim.set("Int32_input", np.int64(3))
        sim.step(0.1)
        assert sim.get(["Float64_continuous_output", "Int32_output"]).tolist() == [0.5, 3.0]
        with pytest.raises(RunnerError, match=r"'Int8_input' is an Int8; 300 is out of its range -128..=127"):
            sim.set("Int8_input", 300)
        with pytest.raises(RunnerError, match="'String_input' is a String"):
            sim.set("String_input", 3)
        with pytest.raises(RunnerError, match="'Boolean_input' is a Boolean"):
            sim.set("Boolean_input", 0.5)


def test_a_start_value_with_a_unit_is_converted_to_si():
    """pendulum's theta0 is in rad with deg as display unit: "15deg" is 15 * pi / 180 rad, the
    same bits as giving the radians; an unknown unit is refused naming the variable's units."""
    with fmurunner.Simulation("pendulum", start_values={"theta0": "15deg"}) as a:
        with fmurunner.Simulation("pendulum", start_values={"theta0": math.radians(15)}) as b:
            assert a.get("theta") == b.get("theta") == math.radians(15)
            a.advance_to(1.0)
            b.advance_to(1.0)
            assert a.get(["theta", "omega"]).tolist() == b.get(["theta", "omega"]).tolist()
    with pytest.raises(RunnerError, match="theta0"):
        fmurunner.Simulation("pendulum", start_values={"theta0": "15furlong"})
    with fmurunner.Simulation(fmu_path("quarter_car")) as sim:
        sim.set("z_r_dot_ext", "0.25m/s")
        sim.step(0.01)
        with pytest.raises(RunnerError, match="z_r_dot_ext"):
            sim.set("z_r_dot_ext", "3deg")


def test_state_bytes_go_back_in_this_and_in_another_simulation():
    """get_state at 0.5 s, run on to 1 s; set_state goes back to 0.5 s (time included) and the
    same steps give the same bits, in this Simulation and in a fresh one of the same FMU."""
    path = fmu_path("quarter_car")

    def run_on(sim):
        out = []
        for _ in range(500):
            sim.step(1e-3)
            out.append(sim.get("z_s"))
        return out

    with fmurunner.Simulation(path) as sim:
        sim.advance_to(0.5)
        state = sim.get_state()
        assert isinstance(state, bytes) and len(state) > 0
        first = run_on(sim)
        sim.set_state(state)
        assert sim.time == 0.5
        assert run_on(sim) == first
    with fmurunner.Simulation(path) as other:
        other.set_state(state)
        assert other.time == 0.5 and run_on(other) == first
        with pytest.raises(RunnerError, match="bytes"):
            other.set_state("not bytes")
        with pytest.raises(RunnerError):
            other.set_state(b"garbage")
        # A refused state leaves the instance failed: only reset() is allowed, and works.
        other.reset()
        assert other.time == 0.0


def test_reset_reuses_the_instance_and_repeats_the_run():
    with fmurunner.Simulation(fmu_path("quarter_car")) as sim:
        sim.advance_to(0.3)
        first = sim.get(["z_s", "z_u"]).tolist()
        sim.reset()
        assert sim.time == 0.0
        sim.advance_to(0.3)
        assert sim.get(["z_s", "z_u"]).tolist() == first
        sim.reset({"speed": 5.0})
        assert sim.get("speed") == 5.0
        sim.advance_to(0.3)
        assert sim.get(["z_s", "z_u"]).tolist() != first


def test_termination_by_the_fmu_raises_its_reason_and_keeps_the_last_values():
    """The FMI 3.0 trebuchet ends the simulation when the projectile lands (terminateSimulation):
    the step raises with the FMU's reason; the time and values it reached can still be read;
    stepping again says the simulation has ended; reset() starts it again."""
    with fmurunner.Simulation(fmu_path("trebuchet").parent.parent / "fmu3" / "trebuchet.fmu") as sim:
        with pytest.raises(RunnerError, match="the projectile landed"):
            while True:
                sim.step(0.05)
        assert 1.0 < sim.time < 10.0 and sim.time % 0.05 > 1e-9, "ended inside a step, where it landed"
        sim.get("time")
        with pytest.raises(RunnerError, match="has ended"):
            sim.step(0.05)
        sim.reset()
        assert sim.step(0.05).time == 0.05


def test_misuse_raises_clear_errors():
    with fmurunner.Simulation(fmu_path("quarter_car"), stop_time=1.0) as sim:
        with pytest.raises(RunnerError, match="did you mean 'z_s'"):
            sim.get("z_ss")
        with pytest.raises(RunnerError, match="did you mean 'z_s'"):
            sim.get(["z_u", "z_ss"])
        with pytest.raises(RunnerError, match="not a variable name"):
            sim.get(["z_u", 3])
        with pytest.raises(RunnerError, match="did you mean 'z_r_dot_ext'"):
            sim.set("z_r_dot_xt", 1.0)
        with pytest.raises(RunnerError, match="only inputs and tunable parameters"):
            sim.set("z_s", 1.0)
        with pytest.raises(RunnerError, match="set before initialization only"):
            sim.set("speed", 1.0)
        with pytest.raises(RunnerError, match="cannot be set"):
            sim.set("z_r_dot_ext", object())
        with pytest.raises(RunnerError, match="finite number"):
            sim.set("z_r_dot_ext", float("nan"))
        with pytest.raises(RunnerError, match="positive"):
            sim.step(-1.0)
        with pytest.raises(RunnerError, match="passes the stop time 1"):
            sim.step(2.0)
        sim.advance_to(0.5)
        with pytest.raises(RunnerError, match="goes forward"):
            sim.advance_to(0.25)
    with pytest.raises(RunnerError, match="closed"):
        sim.step(0.1)
    with pytest.raises(RunnerError, match="closed"):
        sim.get("z_s")
    with pytest.raises(RunnerError, match="closed"):
        sim.time
    sim.close()
    assert sim.closed
    with pytest.raises(RunnerError, match="solver"):
        fmurunner.Simulation(fmu_path("quarter_car"), solver="euler-ish")
    with pytest.raises(RunnerError, match="interface"):
        fmurunner.Simulation(fmu_path("quarter_car"), interface="scheduled")
    with pytest.raises(RunnerError, match="did you mean 'speed'"):
        fmurunner.Simulation("quarter_car", start_values={"sped": 1.0})
    with pytest.raises(RunnerError):
        fmurunner.Simulation("/nonexistent/model.fmu")


def test_a_step_the_fmu_refuses_raises_its_message(tmp_path):
    """faulty.c's fault 7: fmi2DoStep returns fmi2Error from t = 0.31 with a logged reason. The
    error carries it; the instance is then failed (FMI 2.0: only reset or free), and reset() works."""
    fmu = faulty_fmu(tmp_path)
    with fmurunner.Simulation(fmu, start_values={"fault": 7}) as sim:
        sim.advance_to(0.3)
        with pytest.raises(RunnerError, match="this step is refused"):
            while True:
                sim.step(0.01)
        assert abs(sim.time - 0.31) < 1e-9
        with pytest.raises(RunnerError, match="only reset"):
            sim.step(0.01)
        sim.reset({"fault": 0})
        sim.advance_to(1.0)
        assert abs(sim.get("x") - math.exp(-1.0)) < 1e-12


def test_an_isolated_simulation_survives_its_fmu_crashing(tmp_path):
    """isolated=True: the FMU runs in a sandbox worker. faulty.c's fault 1 (SIGSEGV in fmi2DoStep
    at t = 0.31) costs the worker, not this interpreter: the step raises saying what happened
    and where, and reset() starts a fresh worker. The same holds for a hang past timeout."""
    fmu = faulty_fmu(tmp_path)
    with fmurunner.Simulation(fmu, start_values={"fault": 1}, isolated=True) as sim:
        assert sim.get("pid") != os.getpid()
        sim.advance_to(0.3)
        with pytest.raises(RunnerError, match=r"crashed: SIGSEGV in fmi2DoStep at t = 0.31"):
            while True:
                sim.step(0.01)
        sim.reset({"fault": 0})
        sim.advance_to(1.0)
        assert abs(sim.get("x") - math.exp(-1.0)) < 1e-12
    with fmurunner.Simulation(fmu, start_values={"fault": 3}, isolated=True, timeout=0.5) as sim:
        with pytest.raises(RunnerError, match=r"timed out after 0.5 s in fmi2DoStep at t = 0.31"):
            while True:
                sim.step(0.01)
        with pytest.raises(RunnerError, match="reset"):
            sim.get("x")


def test_isolated_and_in_process_give_the_same_bits():
    path = fmu_path("quarter_car")
    with fmurunner.Simulation(path) as a, fmurunner.Simulation(path, isolated=True) as b:
        for k in range(200):
            a.set("z_r_dot_ext", 0.01 * k)
            b.set("z_r_dot_ext", 0.01 * k)
            a.step(1e-3)
            b.step(1e-3)
        assert a.get(["z_s", "z_u", "z_r"]).tolist() == b.get(["z_s", "z_u", "z_r"]).tolist()
        b.set_state(a.get_state())
        assert b.time == a.time


def test_model_exchange_is_integrated_by_the_runners_solver():
    """interface='model-exchange': the runner integrates the FMU's derivatives. Checked against
    the same FMU's Co-Simulation (its own integrator, rtol 1e-6 and abs_tol 1e-9 inside): both
    solve the same ODE, so they agree to about the tolerances, not to the bit (2e-6 m on a
    response of centimetres)."""
    path = fmu_path("quarter_car")
    with fmurunner.Simulation(path, interface="model-exchange", tolerance=1e-9) as me, fmurunner.Simulation(path) as cs:
        for _ in range(100):
            me.step(0.01)
            cs.step(0.01)
            assert abs(me.get("z_s") - cs.get("z_s")) < 2e-6
        assert abs(cs.get("z_s")) > 1e-4, "the road moved the car"


def test_realtime_paces_the_steps_to_the_wall_clock_and_counts_overruns():
    """realtime=1.0: ten steps of 20 ms of simulated time take at least 200 ms of wall clock
    (the first step anchors the clocks at its start). realtime=1e6 asks each 1 ms step to take
    1 ns, which no FMU call does: every step is an overrun."""
    path = fmu_path("quarter_car")
    with fmurunner.Simulation(path, realtime=1.0) as sim:
        start = time.monotonic()
        for _ in range(10):
            sim.step(0.02)
        assert time.monotonic() - start >= 0.2 - 1e-3
    with fmurunner.Simulation(path, realtime=1e6) as sim:
        for _ in range(20):
            sim.step(1e-3)
        assert sim.overruns == 20 and sim.lateness > 0.0
    with fmurunner.Simulation(path) as sim:
        assert (sim.overruns, sim.lateness) == (0, 0.0)
    with pytest.raises(RunnerError, match="realtime|pacing|factor"):
        fmurunner.Simulation(path, realtime=-1.0)


def test_reading_the_same_names_again_or_others_gives_each_its_value():
    """get() reuses the selection of the names read last (compared in place): a tuple, a list,
    the names reordered, one name as a str or in a list each give their own values and shapes."""
    with fmurunner.Simulation(fmu_path("quarter_car")) as sim:
        sim.advance_to(0.1)
        z_s, z_u = sim.get("z_s"), sim.get("z_u")
        assert z_s != z_u
        assert sim.get(["z_s", "z_u"]).tolist() == [z_s, z_u]
        assert sim.get(("z_s", "z_u")).tolist() == [z_s, z_u]
        assert sim.get(["z_u", "z_s"]).tolist() == [z_u, z_s]
        assert sim.get(["z_s"]).tolist() == [z_s]
        assert sim.get("z_s") == z_s and isinstance(sim.get("z_s"), float)
        assert sim.get(["z_s", "speed"]).tolist() == [z_s, 30.0]


def test_model_exchange_agrees_with_fmpys_cvode_on_the_same_fmu():
    """Model Exchange stepped by Simulation (the runner's integrator, rtol 1e-9) against fmpy's
    FMU2Model with its CVODE loop (simulate_fmu, rtol 1e-9), pendulum from 15 degrees: two
    integrators of the same derivatives, so the same angle to about the tolerances (1e-6 rad on
    an amplitude of 0.26 rad), at each 10 ms for 2 s."""
    from fmpy import simulate_fmu

    path = fmu_path("pendulum")
    theirs = simulate_fmu(str(path), fmi_type="ModelExchange", solver="CVode", relative_tolerance=1e-9,
                          output_interval=0.01, stop_time=2.0, output=["theta"])
    with fmurunner.Simulation(path, interface="model-exchange", tolerance=1e-9) as sim:
        assert sim.get("theta") == theirs["theta"][0]
        worst = 0.0
        for t, theta in zip(theirs["time"][1:], theirs["theta"][1:]):
            sim.advance_to(float(t))
            worst = max(worst, abs(sim.get("theta") - theta))
        assert worst < 1e-6, worst
        assert min(theirs["theta"]) < -0.2, "the pendulum swung through"


def test_a_second_thread_calling_during_a_call_gets_an_error():
    """One call at a time: while a paced step holds the simulation (0.3 s of wall clock, the GIL
    released), another thread's call raises RunnerError instead of waiting or racing."""
    import threading

    with fmurunner.Simulation(fmu_path("quarter_car"), realtime=1.0) as sim:
        sim.step(1e-3)  # anchors the pacing's clocks
        stepping = threading.Thread(target=lambda: sim.step(0.3))
        stepping.start()
        time.sleep(0.1)
        with pytest.raises(RunnerError, match="in use by another thread"):
            sim.get("z_s")
        stepping.join()
        assert abs(sim.time - 0.301) < 1e-12


def test_fmi2_feedthrough_sets_and_gets_every_type_as_fmpy_reads_them():
    """FMI 2.0 Feedthrough: Real, Integer, Boolean, String and Enumeration inputs set through
    Simulation come back on its outputs with their Python types, the same values fmpy's
    FMU2Slave reads after making the same calls."""
    path = REFERENCE / "fmi2" / "Feedthrough.fmu"
    values = {"Float64_continuous_input": -1.25, "Int32_input": 2**31 - 1, "Boolean_input": True,
              "String_input": "abc", "Enumeration_input": 2}
    theirs = FmpySlave(path)
    with fmurunner.Simulation(path) as sim:
        for name, value in values.items():
            sim.set(name, value)
            theirs.set(name, value)
        sim.step(0.1)
        theirs.step(0.1)
        for name, value in values.items():
            output = name.replace("_input", "_output")
            got = sim.get(output)
            assert got == value == theirs.get(output) and type(got) is type(value), (output, got)
        # Read together, in one reader (fmi2GetString beside fmi2GetReal and fmi2GetInteger).
        assert sim.get(["String_output", "Float64_continuous_output", "Int32_output"]) == ["abc", -1.25, 2**31 - 1]
        with pytest.raises(RunnerError, match="out of its range"):
            sim.set("Int32_input", 2**31)
    theirs.close()


def test_results_held_keep_their_values_while_dropped_ones_are_refilled():
    """step() and get() refill the result they returned last once nothing holds it (a loop that
    drops them allocates nothing): a result still held, or an array reshaped or made read-only
    in place, is never refilled, and each keeps the values it was returned with."""
    with fmurunner.Simulation(fmu_path("quarter_car")) as sim:
        names = ["z_s", "z_u"]
        first = sim.step(0.1)
        values = sim.get(names)
        before = values.tolist()
        second = sim.step(0.1)
        after = sim.get(names)
        assert (first.time, second.time) == (0.1, 0.2) and after is not values
        assert values.tolist() == before != after.tolist()
        for _ in range(3):  # dropped at once, refilled, still the values of this time
            sim.step(0.1)
            assert sim.get(names).tolist() == [sim.get("z_s"), sim.get("z_u")]
            assert sim.step(0.0 + 0.1).time == sim.time
        changed = sim.get(names)
        changed.shape = (2, 1)
        del changed
        assert sim.get(names).shape == (2,)
        frozen = sim.get(names)
        frozen.flags.writeable = False
        del frozen
        assert sim.get(names).flags.writeable


def test_an_array_input_takes_a_numpy_array_of_its_size():
    """FMI 3.0 StateSpace: its input vector u, sized by the structural parameter m (3), set from
    a numpy array reads back as the same float64 array; an array of another length is refused
    before the FMU sees it (which would fail the instance), naming the size, and the simulation
    goes on."""
    with fmurunner.Simulation(REFERENCE / "fmi3" / "StateSpace.fmu") as sim:
        sim.set("u", np.array([4.0, 5.0, 6.0]))
        got = sim.get("u")
        assert isinstance(got, np.ndarray) and got.dtype == np.float64 and got.tolist() == [4.0, 5.0, 6.0]
        sim.set("u", np.arange(3, dtype=np.int32))
        assert sim.get("u").tolist() == [0.0, 1.0, 2.0]
        with pytest.raises(RunnerError, match="'u' has 3 elements; 2 were given"):
            sim.set("u", np.zeros(2))
        sim.step(0.1)
        assert sim.get("u").tolist() == [0.0, 1.0, 2.0]
