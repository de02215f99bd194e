"""Bad inputs at the C boundary of every model's real FMU (issue "Reliability").

Driven through fmpy's low-level API: each model's binary is loaded once by `fmpy.fmi2.FMU2Slave`
and its `fmi2*` functions are called directly through the ctypes functions fmpy configured
(`FMU2Slave.dll`), so every call's status is seen as returned instead of as an exception, and
NULL pointers and empty arrays can be passed. The logger keeps every message.

1. Bad parameter values: NaN and +-inf for every Real parameter and input, refused at
   fmi2SetReal; zero and negative values that make no physical sense (the explicit table
   `RULES` below, one line per parameter, for a reviewer to check against MODELS.md and each
   model's derivation.md), refused at fmi2SetReal or fmi2ExitInitializationMode; mechanisms
   that cannot be assembled, refused at initialization saying so.
2. Diverging runs: forward Euler with a huge fixed_step (or what breaks a kinematically driven
   mechanism) stepped until it fails: every step is fmi2OK with finite values or fmi2Discard /
   fmi2Error with a message, and nothing non-finite is ever returned with fmi2OK.
3. Arrays and references: nvr = 0 with NULL arrays, NULL arrays with nvr > 0, NULL
   instances, unknown and wrongly typed value references, and setting fixed parameters or
   outputs after initialization, for all eight get/set functions of every model.

Single-model versions of some of these live in test_fmi_boundary.py; these run over MODELS.
"""

import ctypes
import math
import re
from ctypes import byref, c_char_p, c_double, c_int, c_size_t, c_uint

import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

from conftest import MODELS, fmu_path

OK, WARNING, DISCARD, ERROR = 0, 1, 2, 3
REFUSED = (DISCARD, ERROR)  # what the issue accepts for a refused value
NAN, INF = float("nan"), float("inf")
CONTROLS = {"solver", "fixed_step", "abs_tol", "max_step", "n_steps", "n_rhs"}

C_TYPE = {"Real": c_double, "Integer": c_int, "Boolean": c_int, "String": c_char_p}


class Probe:
    """One model's FMU, loaded once; instances are made and freed with raw FMI calls and every
    call returns its status. `log` holds (status, message) of everything the FMU logged."""

    def __init__(self, model, directory):
        self.model = model
        self.md = read_model_description(str(fmu_path(model)))
        self.vars = {v.name: v for v in self.md.modelVariables}
        unzipped = extract(str(fmu_path(model)), unzipdir=str(directory / model))
        self.log = []
        self.callbacks = fmi2CallbackFunctions()
        self._logger = fmi2CallbackLoggerTYPE(lambda env, name, status, cat, msg: self.log.append((status, msg.decode())))
        self.callbacks.logger = self._logger
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(lambda n, s: None)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(lambda p: None)
        self.slave = FMU2Slave(guid=self.md.guid, unzipDirectory=unzipped,
                               modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=model)
        self.lib = self.slave.dll  # the ctypes functions, argtypes set by fmpy, no status checks
        self.live = []

    # -- instances ---------------------------------------------------------------------------
    def new(self, state="Instantiated", reals=None, integers=None):
        """A fresh instance driven to `state` ("Instantiated", "InitializationMode" or
        "StepComplete"), with `reals` / `integers` ({name: value}) set while instantiated."""
        self.slave.instantiate(callbacks=self.callbacks)
        c = self.slave.component
        self.live.append(c)
        for name, value in (integers or {}).items():
            assert self.set(c, "Integer", [self.vr(name)], [value]) == OK, self.messages()
        for name, value in (reals or {}).items():
            assert self.set(c, "Real", [self.vr(name)], [value]) == OK, self.messages()
        if state == "Instantiated":
            return c
        assert self.call("fmi2SetupExperiment", c, 0, 0.0, 0.0, 0, 0.0) == OK, self.messages()
        assert self.call("fmi2EnterInitializationMode", c) == OK, self.messages()
        if state == "InitializationMode":
            return c
        assert self.call("fmi2ExitInitializationMode", c) == OK, self.messages()
        assert state == "StepComplete"
        return c

    def close(self):
        for c in self.live:
            self.lib.fmi2FreeInstance(c)
        self.live.clear()

    # -- calls -------------------------------------------------------------------------------
    def call(self, name, *args):
        """Calls fmi2<name> and returns its status; the log is cleared first, so `messages()`
        is what this one call logged."""
        self.log.clear()
        return getattr(self.lib, name)(*args)

    def messages(self):
        return " | ".join(m for _, m in self.log)

    def vr(self, name):
        return self.vars[name].valueReference

    def set(self, c, kind, vrs, values):
        arr = (c_uint * len(vrs))(*vrs)
        vals = (C_TYPE[kind] * len(vrs))(*values)
        return self.call(f"fmi2Set{kind}", c, arr, len(vrs), vals)

    def get(self, c, kind, vrs):
        arr = (c_uint * len(vrs))(*vrs)
        vals = (C_TYPE[kind] * len(vrs))()
        return self.call(f"fmi2Get{kind}", c, arr, len(vrs), vals), list(vals)

    def get_reals(self, c, names=None):
        """Reads Real variables (all by default). Whatever the state: a read with fmi2OK must
        give finite numbers (never a silent NaN or inf), and a refused read must say why."""
        names = names or [v.name for v in self.md.modelVariables if v.type == "Real"]
        status, values = self.get(c, "Real", [self.vr(n) for n in names])
        if status == OK:
            bad = {n: v for n, v in zip(names, values) if not math.isfinite(v)}
            assert not bad, f"{self.model}: fmi2GetReal returned fmi2OK with non-finite values {bad}"
        else:
            assert status == ERROR and self.log, f"{self.model}: fmi2GetReal returned {status} without a message"
        return status, dict(zip(names, values))

    def variables(self, causality=None, type=None):
        return [v for v in self.md.modelVariables
                if (causality is None or v.causality in causality) and (type is None or v.type == type)]


@pytest.fixture(scope="module")
def probes(tmp_path_factory):
    """Model name -> Probe, each FMU extracted and loaded once for this file."""
    directory = tmp_path_factory.mktemp("bad_inputs")
    made = {}

    def probe(model):
        if model not in made:
            made[model] = Probe(model, directory)
        return made[model]

    yield probe
    for p in made.values():
        p.close()


@pytest.fixture
def probe(probes, request):
    """The Probe of the test's `model` parameter; its instances are freed afterwards."""
    p = probes(request.node.callspec.params["model"])
    yield p
    p.close()


def names_variable(message, name):
    """True when `message` names variable `name` as `name = value` or `'name'` (a whole word:
    "m" must not match inside "m_s")."""
    word = re.escape(name)
    return re.search(rf"(?<![\w']){word}(?![\w'])\s*=|'{word}'", message) is not None


# ------------------------------------------------------------------------------------------
# 1. Bad parameter values
# ------------------------------------------------------------------------------------------

# Which values of each Real parameter make physical sense, decided per parameter from
# MODELS.md and the model's derivation.md. Every Real parameter of every FMU is listed (the
# test below fails if one is missing), so a new parameter forces a decision here.
#   positive      zero and negative values are refused: lengths, masses, stiffnesses, weights,
#                 wavelengths, gravity where the model needs it pointing down, the step size
#   non_negative  negative values are refused, zero is a meaningful limit case and accepted:
#                 dampers and friction (undamped), a spring (k = 0: a free mass), the car's
#                 speed (at rest), the inverted crank-slider's masses and inertia (derivation.md
#                 checks a massless link 3), abs_tol (pure relative tolerance)
#   nonzero       zero is refused (a2 = 0 is no longer a second-order equation); both signs are
#                 the same equation scaled
#   any           every finite value means something: initial values, angles, signed angular
#                 velocities (omega < 0 turns clockwise), generic ODE coefficients, the road's
#                 amplitude (its sign is a phase), the slider line's height
RULES = {
    "second_order": {"a2": "nonzero", "a1": "any", "a0": "any", "q0": "any", "q_dot0": "any"},
    "mass_spring_damper": {"m": "positive", "b": "non_negative", "k": "non_negative", "x0": "any", "v0": "any"},
    "pendulum": {"L": "positive", "m": "positive", "g": "positive", "theta0": "any", "omega0": "any",
                 "c": "non_negative"},
    # B > 0: after the release the massless plate obeys B x' + K x = 0; V0 > 0: the mass must
    # move toward the bumper for there to be a collision.
    "bumper": {"M": "positive", "K": "positive", "B": "positive", "V0": "positive"},
    # The springs carry the static weight the derivation subtracts, so k_s, k_t > 0.
    "quarter_car": {"m_s": "positive", "m_u": "positive", "k_s": "positive", "b_s": "non_negative",
                    "k_t": "positive", "b_t": "non_negative", "speed": "non_negative",
                    "road_amplitude": "any", "road_wavelength": "positive"},
    "crank_slider": {"l_OA": "positive", "l_AB": "positive", "theta0": "any", "omega": "any"},
    "offset_crank_slider": {"l_OA": "positive", "l_AB": "positive", "y_OC": "any", "theta0": "any",
                            "omega": "any"},
    "crank_rocker": {"l_OA": "positive", "l_AB": "positive", "l_BC": "positive", "l_CO": "positive",
                     "theta_CO": "any", "theta0": "any", "omega": "any"},
    "double_rocker": {"l_OA": "positive", "l_AB": "positive", "l_BC": "positive", "l_CO": "positive",
                      "theta_CO": "any", "theta0": "any", "omega": "any"},
    "inverted_crank_slider": {"r1": "positive", "r2": "positive", "L3": "positive", "omega": "any",
                              "theta2_0": "any", "m2": "non_negative", "m3": "non_negative",
                              "I3": "non_negative"},
    # rho (N/m) and the weights w_B, w_3 (N) are weights; g > 0 points gravity down (-y).
    "trebuchet": {"r_AC": "positive", "r_BC": "positive", "r_CD": "positive", "r_DE": "positive",
                  "rho": "positive", "w_B": "positive", "w_3": "positive", "g": "positive",
                  "theta1_0": "any", "theta2_0": "any", "theta3_0": "any", "release_angle": "any"},
    # A negative speed drives the wheel backwards, a negative height is a dip.
    "road": {"speed": "any", "amplitude": "any", "wavelength": "positive", "bump_height": "any",
             "bump_length": "positive", "bump_start": "any"},
}
# The toolkit's solver controls, the same in every FMU.
CONTROL_RULES = {"fixed_step": "positive", "abs_tol": "non_negative"}

# What a refusal must say, besides the variable's name.
REASON = {
    "positive": r"greater than (zero|0)",
    "non_negative": r"zero or greater|not be negative|>= ?0",
    "nonzero": r"not be zero",
}


def refused_values(rule, start):
    """The values `rule` refuses, built from the start value's magnitude."""
    negative = -abs(start) if start else -1.0
    return {"positive": [0.0, negative], "non_negative": [negative], "nonzero": [0.0], "any": []}[rule]


def test_rules_table_lists_every_real_parameter(probes):
    """The table above is complete: a Real parameter without a decision fails here."""
    for model in MODELS:
        p = probes(model)
        declared = {v.name for v in p.variables({"parameter"}, "Real")} - CONTROLS
        assert set(RULES[model]) == declared, model


@pytest.mark.parametrize("model", MODELS)
def test_non_finite_values_are_refused_at_set_real(probe, model):
    """NaN, +inf and -inf for every Real parameter (the solver controls included) and every
    Real input are refused by fmi2SetReal itself, the earliest point, with fmi2Error naming the
    variable, in every state where the variable may be set; a refused call changes nothing
    (not even the valid values before the bad one in the same call), so initialization then
    succeeds with the start values."""
    settable = probe.variables({"parameter", "input"}, "Real")
    inputs = [v for v in settable if v.causality == "input"]
    checked = 0

    def refuse_all(c, variables):
        nonlocal checked
        for v in variables:
            for bad in (NAN, INF, -INF):
                status = probe.set(c, "Real", [v.valueReference], [bad])
                msg = probe.messages()
                assert status in REFUSED, f"{model}: {v.name} = {bad} accepted"
                assert names_variable(msg, v.name) and "finite" in msg, f"{model}: {v.name} = {bad}: {msg!r}"
                checked += 1
            # All or nothing: a valid value for another variable, then a NaN for this one.
            first = variables[0] if variables[0] is not v else variables[-1]
            status = probe.set(c, "Real", [first.valueReference, v.valueReference], [float(first.start) + 0.5, NAN])
            assert status in REFUSED and names_variable(probe.messages(), v.name)

    c = probe.new("Instantiated")
    refuse_all(c, settable)
    assert probe.call("fmi2SetupExperiment", c, 0, 0.0, 0.0, 0, 0.0) == OK
    assert probe.call("fmi2EnterInitializationMode", c) == OK
    refuse_all(c, settable)
    status, values = probe.get_reals(c, [v.name for v in settable])
    assert status == OK, probe.messages()
    for v in settable:
        assert values[v.name] == float(v.start), f"{model}: a refused fmi2SetReal changed {v.name}"
    assert probe.call("fmi2ExitInitializationMode", c) == OK, probe.messages()
    # Inputs stay settable between steps, and stay checked.
    refuse_all(c, inputs)
    assert probe.call("fmi2DoStep", c, 0.0, 1e-3, 1) == OK, probe.messages()
    probe.get_reals(c)
    assert checked == 3 * (2 * len(settable) + len(inputs))


def _refusal(probe, model, name, value, kind="Real"):
    """Sets `name` = `value` on a fresh instance and initializes. Returns (where, message):
    where is "fmi2SetReal" / "fmi2SetInteger" or "fmi2ExitInitializationMode" if refused
    there, None if accepted (then the FMU must also step)."""
    c = probe.new("Instantiated")
    status = probe.set(c, kind, [probe.vr(name)], [value])
    if status != OK:
        assert status in REFUSED, f"{model}: {name} = {value}: status {status}"
        return f"fmi2Set{kind}", probe.messages()
    assert probe.call("fmi2SetupExperiment", c, 0, 0.0, 0.0, 0, 0.0) == OK
    assert probe.call("fmi2EnterInitializationMode", c) == OK
    status = probe.call("fmi2ExitInitializationMode", c)
    if status != OK:
        assert status in REFUSED, f"{model}: {name} = {value}: status {status}"
        return "fmi2ExitInitializationMode", probe.messages()
    status = probe.call("fmi2DoStep", c, 0.0, 1e-3, 1)
    assert status in (OK, DISCARD), f"{model}: {name} = {value} accepted but the first step: {probe.messages()}"
    probe.get_reals(c)
    return None, ""


@pytest.mark.parametrize("model", MODELS)
def test_unphysical_values_are_refused_naming_the_variable_and_why(probe, model):
    """Zero or negative values the RULES table forbids are refused (at fmi2SetReal or at
    fmi2ExitInitializationMode) with a message naming the variable and the rule it breaks;
    zero for a non_negative parameter is a valid limit case and must initialize and step."""
    rules = {**RULES[model], **CONTROL_RULES}
    checked = 0
    for name, rule in rules.items():
        start = float(probe.vars[name].start)
        for value in refused_values(rule, start):
            where, msg = _refusal(probe, model, name, value)
            assert where, f"{model}: {name} = {value} was accepted ({rule})"
            assert names_variable(msg, name), f"{model}: {name} = {value}: {msg!r} does not name {name}"
            assert re.search(REASON[rule], msg), f"{model}: {name} = {value}: {msg!r} does not say why ({rule})"
            checked += 1
        if rule == "non_negative":
            where, msg = _refusal(probe, model, name, 0.0)
            assert where is None, f"{model}: {name} = 0 refused at {where}: {msg}"
        probe.close()
    assert checked == sum(len(refused_values(r, 1.0)) for r in rules.values())


@pytest.mark.parametrize("model", ["crank_slider", "offset_crank_slider", "crank_rocker", "double_rocker"])
def test_branch_other_than_plus_or_minus_one_is_refused(probe, model):
    """The assembly choice `branch` is +1 or -1; anything else is refused, naming it."""
    for value in (0, 2, -3):
        where, msg = _refusal(probe, model, "branch", value, kind="Integer")
        assert where and names_variable(msg, "branch") and "+1 or -1" in msg, msg
        probe.close()


@pytest.mark.parametrize("model", MODELS)
def test_unknown_solver_is_refused_at_set_integer(probe, model):
    """`solver` takes 0 to 6 (6: ESDIRK); other codes are refused by fmi2SetInteger, naming it
    and the valid choices (test_fmi_boundary.py checks one model; this checks the table of every
    FMU)."""
    c = probe.new("Instantiated")
    for value in (-1, 7, 9):
        assert probe.set(c, "Integer", [probe.vr("solver")], [value]) == ERROR
        assert names_variable(probe.messages(), "solver") and "forward Euler" in probe.messages()


# Parameter sets at which a mechanism cannot be put together at its initial position (or, for
# the trebuchet, starts in an impossible configuration), and what the refusal must say.
# Lengths in m, angles in rad; the other parameters keep their defaults (MODELS.md).
CANNOT_ASSEMBLE = [
    # Rod shorter than the crank pin's height above the slider line: B cannot reach the line.
    ("crank_slider", {"l_AB": 0.05}, "cannot be assembled"),
    ("offset_crank_slider", {"y_OC": 0.3}, "cannot be assembled"),
    ("offset_crank_slider", {"l_AB": 0.005}, "cannot be assembled"),
    # |AC| at theta0 = 135 deg is 0.635 m > l_AB + l_BC: the triangle ABC does not close.
    ("crank_rocker", {"l_BC": 0.1}, "cannot be assembled"),
    # |AC| < |l_AB - l_BC|: the other side of the triangle inequality.
    ("crank_rocker", {"l_AB": 0.9, "l_BC": 0.1}, "cannot be assembled"),
    # MODELS.md: the double rocker cannot be assembled at 150 deg with C on the +x axis.
    ("double_rocker", {"theta_CO": 0.0}, "cannot be assembled"),
    # Link BD shorter than the C-B distance at the start (r1 + r2 = 0.32 m at theta2 = 0):
    # it does not reach through the collar.
    ("inverted_crank_slider", {"L3": 0.3}, "cannot be assembled"),
    # Assembles at theta2 = 180 deg (C-B = 0.16 m) but BD leaves the collar at theta2 = 0.
    ("inverted_crank_slider", {"L3": 0.2, "theta2_0": math.pi}, "leave the collar"),
    # A crank longer than the ground distance drives B through the collar pivot C.
    ("inverted_crank_slider", {"r2": 0.3}, "r2 < r1"),
    # The trebuchet's starting configuration must have A and B above the ground.
    # theta1 = 90 deg hangs A straight below C, which is 0.44 m up: A starts below the ground.
    ("trebuchet", {"theta1_0": math.pi / 2}, "above the ground"),
    ("trebuchet", {"release_angle": 0.5}, "must exceed"),
]


@pytest.mark.parametrize("model,params,says", CANNOT_ASSEMBLE, ids=[f"{m}-{'-'.join(p)}" for m, p, _ in CANNOT_ASSEMBLE])
def test_mechanisms_that_cannot_be_assembled_are_refused_at_initialization(probes, model, params, says):
    """Geometry that cannot be assembled is accepted by fmi2SetReal (each value is fine alone)
    and refused by fmi2ExitInitializationMode with fmi2Error, saying why and naming a parameter."""
    probe = probes(model)
    c = probe.new("InitializationMode", reals=params)
    try:
        assert probe.call("fmi2ExitInitializationMode", c) == ERROR, f"{model} {params} initialized"
        msg = probe.messages()
        assert says in msg, msg
        assert any(name in msg for name in params), msg
    finally:
        probe.close()


def test_finite_parameters_that_overflow_an_output_are_refused(probes):
    """Finite but absurd parameters whose initial outputs overflow (the pendulum's energy
    m g L (1 - cos theta0) = inf for m = 1e300, L = 1e10) are refused at initialization naming
    the output, instead of starting a run whose outputs are inf."""
    probe = probes("pendulum")
    c = probe.new("InitializationMode", reals={"m": 1e300, "L": 1e10})
    try:
        status, _ = probe.get_reals(c, ["energy"])
        assert status == ERROR and names_variable(probe.messages(), "energy")
        assert probe.call("fmi2ExitInitializationMode", c) == ERROR
        assert names_variable(probe.messages(), "energy") and "finite" in probe.messages()
    finally:
        probe.close()


# ------------------------------------------------------------------------------------------
# 2. Non-finite or diverging states
# ------------------------------------------------------------------------------------------

# Per model: parameters, forward Euler's fixed_step, the communication step, and how the run
# must end. Stable ODEs blow up when h |lambda| >> 2; the pendulum needs friction to diverge
# (c = 1: h c / (m L^2) = 36 per step); the mass-spring-damper must start off equilibrium.
# The kinematically driven mechanisms are re-closed at every communication point, so a huge
# step shows up as a limit position (fmi2Discard); the inverted crank-slider's loop closes at
# every crank angle, so it is broken by Euler steps of half a crank turn, after which Newton's
# projection cannot close the loop on r3 > 0 (fmi2Error); the trebuchet misfires.
DIVERGE = {
    "second_order": ({}, 10.0, 10.0, "error"),
    "mass_spring_damper": ({"x0": 0.1}, 10.0, 10.0, "error"),
    "pendulum": ({"c": 1.0}, 10.0, 10.0, "error"),
    "bumper": ({}, 10.0, 10.0, "error"),
    "quarter_car": ({}, 10.0, 10.0, "error"),
    "crank_slider": ({}, 10.0, 10.0, "discard"),
    "offset_crank_slider": ({}, 10.0, 10.0, "discard"),
    "crank_rocker": ({}, 10.0, 10.0, "discard"),
    "double_rocker": ({}, 10.0, 10.0, "discard"),
    "inverted_crank_slider": ({}, 0.5, 1.0, "error"),
    "trebuchet": ({}, 10.0, 10.0, "discard"),
    # x' = speed is stable under any step; at 1e308 m/s one Euler step of 10 s overflows x.
    "road": ({"speed": 1e308}, 10.0, 10.0, "error"),
}
MAX_STEPS = 3000


def _run_until_failure(probe, model, params, fixed_step, h, solver=0):
    """Steps until the first non-OK status; returns that status (OK if none within MAX_STEPS).
    After each OK step every Real variable must read back finite with fmi2OK; after a failure
    the reads must be finite or refused with a message, further steps are refused, and a
    Discard sets fmi2Terminated."""
    c = probe.new("StepComplete", reals={**params, "fixed_step": fixed_step}, integers={"solver": solver})
    t = 0.0
    for k in range(MAX_STEPS):
        status = probe.call("fmi2DoStep", c, t, h, 1)
        step_log = list(probe.log)
        if status == OK:
            # Outputs are computed when read: one that overflowed (an energy ~ omega^2 grows
            # before the states do) is refused there, naming it, and the instance is in Error.
            read, _ = probe.get_reals(c)
            t += h
            if read == OK:
                continue
            assert read == ERROR and "is not finite" in probe.messages(), f"{model}: step {k}: read {read}: {probe.messages()}"
            assert probe.call("fmi2DoStep", c, t, h, 1) == ERROR, f"{model}: a step after the failed read was accepted"
            return ERROR
        assert status in (DISCARD, ERROR), f"{model}: fmi2DoStep returned {status}"
        assert any(s == status and m for s, m in step_log), f"{model}: fmi2DoStep returned {status} without a message"
        probe.get_reals(c)
        ints = [v.valueReference for v in probe.variables(type="Integer")]
        probe.get(c, "Integer", ints)
        if status == DISCARD:
            terminated = c_int(0)
            assert probe.call("fmi2GetBooleanStatus", c, 3, byref(terminated)) == OK and terminated.value
        assert probe.call("fmi2DoStep", c, t, h, 1) == ERROR, f"{model}: a step after the failure was accepted"
        probe.get_reals(c)
        return status
    return OK


@pytest.mark.parametrize("model", MODELS)
def test_diverging_forward_euler_fails_with_a_message_never_a_silent_nan(probe, model):
    """Forward Euler with a step far beyond its stability limit (DIVERGE): every step ends in
    fmi2OK with finite values, or in fmi2Discard / fmi2Error with a log message; reads after
    the failure never return NaN or inf with fmi2OK. The run must actually fail (a test of the
    failure path that never fails tests nothing)."""
    params, fixed_step, h, expected = DIVERGE[model]
    status = _run_until_failure(probe, model, params, fixed_step, h)
    assert status == {"error": ERROR, "discard": DISCARD}[expected], f"{model}: ended with {status}, expected {expected}"


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("solver", [0, 1])
def test_huge_fixed_steps_never_return_silent_nans(probe, model, solver):
    """The same invariant with a fixed step of 1000 s for forward Euler and RK4 (a step from
    t = 0 to 1000 for every model), ending however it ends."""
    params = DIVERGE[model][0]
    _run_until_failure(probe, model, params, 1e3, 1e3, solver=solver)


# ------------------------------------------------------------------------------------------
# 3. Array lengths, NULL pointers, value references, when a variable may be set
# ------------------------------------------------------------------------------------------

KINDS = ["Real", "Integer", "Boolean", "String"]


def _some_vr(probe, kind):
    """A variable of `kind`, or None (no model has String variables)."""
    vs = probe.variables(type=kind)
    return vs[0].valueReference if vs else None


@pytest.mark.parametrize("model", MODELS)
def test_empty_and_null_arrays(probe, model):
    """nvr = 0 with NULL arrays is a successful no-op for all eight get/set functions; nvr > 0
    with a NULL vr[] or value[] is fmi2Error with a message naming the call and the NULL
    argument (never a crash), in initialization mode and after it."""
    for state in ("InitializationMode", "StepComplete"):
        c = probe.new(state)
        for kind in KINDS:
            for op in ("Get", "Set"):
                fn = f"fmi2{op}{kind}"
                assert probe.call(fn, c, None, 0, None) == OK, f"{model} {fn}(nvr=0) in {state}: {probe.messages()}"
                assert not probe.log, f"{fn}(nvr=0) logged {probe.messages()}"
                vr = (c_uint * 1)(_some_vr(probe, kind) or 0)
                value = (C_TYPE[kind] * 1)()
                if op == "Set" and kind == "String":
                    value = (c_char_p * 1)(b"x")
                for args, what in (((None, 1, value), "vr[]"), ((vr, 1, None), "value[]")):
                    assert probe.call(fn, c, *args) == ERROR, f"{model} {fn} with NULL {what} in {state}"
                    msg = probe.messages()
                    assert fn in msg and what in msg and "NULL" in msg, msg
        # The other functions that take arrays or result pointers.
        assert probe.call("fmi2SetDebugLogging", c, 0, 0, None) == OK
        assert probe.call("fmi2SetDebugLogging", c, 1, 2, None) == ERROR and "NULL" in probe.messages()
        if state == "StepComplete":
            for fn, kind in (("fmi2GetStatus", 0), ("fmi2GetRealStatus", 2), ("fmi2GetBooleanStatus", 3)):
                assert probe.call(fn, c, kind, None) == ERROR and "NULL" in probe.messages(), fn
        probe.close()


@pytest.mark.parametrize("model", MODELS)
def test_null_instance_is_an_error_not_a_crash(probe, model):
    """A NULL fmi2Component is refused with fmi2Error by every get/set function and by the
    calls that change state (there is no logger to tell, so only the status says it)."""
    d = (c_double * 1)()
    vr = (c_uint * 1)(0)
    for kind in KINDS:
        for op in ("Get", "Set"):
            value = (C_TYPE[kind] * 1)() if kind != "String" else (c_char_p * 1)(b"x")
            assert probe.call(f"fmi2{op}{kind}", None, vr, 1, value) == ERROR
    assert probe.call("fmi2DoStep", None, 0.0, 0.1, 1) == ERROR
    assert probe.call("fmi2ExitInitializationMode", None) == ERROR
    assert probe.call("fmi2GetRealStatus", None, 2, d) == ERROR


@pytest.mark.parametrize("model", MODELS)
def test_unknown_and_wrongly_typed_value_references_are_named(probe, model):
    """A value reference that is no variable of the FMU, or a variable of another type than
    the function's, is fmi2Error with a message naming the reference, for every get/set
    function; for a wrongly typed one the message also names the variable. Getters are tried
    after initialization, setters before it (so that only the type is wrong)."""
    n = len(probe.md.modelVariables)
    for op, state, causalities in (("Get", "StepComplete", None), ("Set", "Instantiated", {"parameter", "input"})):
        c = probe.new(state)
        for kind in KINDS:
            fn = f"fmi2{op}{kind}"
            value = (C_TYPE[kind] * 1)() if kind != "String" else (c_char_p * 1)(b"x")
            for vr in (n, n + 1000, 2**32 - 1):
                assert probe.call(fn, c, (c_uint * 1)(vr), 1, value) == ERROR, f"{model} {fn}({vr})"
                assert str(vr) in probe.messages(), f"{fn}({vr}): {probe.messages()!r}"
            # One variable of each other type.
            wrong = {v.type: v for v in reversed(probe.variables(causalities)) if v.type != kind}
            assert wrong
            for v in wrong.values():
                assert probe.call(fn, c, (c_uint * 1)(v.valueReference), 1, value) == ERROR, f"{model} {fn}({v.name})"
                msg = probe.messages()
                assert str(v.valueReference) in msg and names_variable(msg, v.name), f"{fn}({v.name}): {msg!r}"
    # An unknown reference among good ones fails the whole call.
    c = probe.new("StepComplete")
    status, _ = probe.get(c, "Real", [_some_vr(probe, "Real"), n + 7])
    assert status == ERROR and str(n + 7) in probe.messages()


@pytest.mark.parametrize("model", MODELS)
def test_fixed_parameters_outputs_and_constants_cannot_be_set_after_initialization(probe, model):
    """After fmi2ExitInitializationMode every fixed parameter (Real, Integer, Boolean, String,
    the solver controls included) and every constant is refused by fmi2Set* with fmi2Error naming
    it and saying why, even when the value is unchanged; outputs are refused in every state.
    The refused calls leave the instance working: it still steps."""
    c = probe.new("StepComplete")
    params = probe.variables({"parameter", "calculatedParameter"})
    constants = [v for v in probe.md.modelVariables if v.variability == "constant"]
    for v in params + constants:
        value = {"Real": float, "Boolean": lambda s: int(s == "true"), "String": str.encode}.get(v.type, int)(v.start)
        assert probe.set(c, v.type, [v.valueReference], [value]) == ERROR, f"{model}: {v.name} set after initialization"
        msg = probe.messages()
        assert f"'{v.name}'" in msg and ("fixed" in msg or "constant" in msg or "calculated" in msg), msg
    assert len(params) >= len(RULES[model]) + 3
    for state in ("Instantiated", "StepComplete"):
        d = probe.new(state)
        for v in probe.variables({"output", "local"}):
            if v.type == "Real" or v.type == "Integer" or v.type == "Boolean":
                assert probe.set(d, v.type, [v.valueReference], [0]) == ERROR, f"{model}: output {v.name} set"
                assert f"'{v.name}'" in probe.messages() and "cannot be set" in probe.messages()
    assert probe.call("fmi2DoStep", c, 0.0, 1e-3, 1) in (OK, DISCARD), probe.messages()
    probe.get_reals(c)
