"""Every FMU as a Model Exchange FMU under a foreign solver: fmpy's CVODE (BDF, fmi_type=
'ModelExchange') integrates it through the FMU's derivatives and event indicators, and the
results meet the same independent references as the Co-Simulation runs (closed forms, the
bumper's release time, the quarter car's transmissibility, the pendulum's elliptic-integral
period, the limit positions), the trebuchet lands where its Co-Simulation run lands, and the
ModelStructure declares the dependencies the derivations give.

Tolerances: fmpy gives CVODE atol = rtol times the nominal (1), and BDF's global error at a
given rtol is larger than the toolkit's DOPRI5's, so each test states the error it measured
and the bound it allows."""

import ctypes

import numpy as np
import pytest
from fmpy import extract, instantiate_fmu, read_model_description, simulate_fmu
from closed_form import reference, references
from conftest import MODELS, fmu_path
from test_lab_models import zero_crossings
from test_mechanisms import closed, defaults, wrap

FMI2_ME_FUNCTIONS = """
fmi2EnterEventMode fmi2NewDiscreteStates fmi2EnterContinuousTimeMode fmi2CompletedIntegratorStep
fmi2SetTime fmi2SetContinuousStates fmi2GetDerivatives fmi2GetEventIndicators
fmi2GetContinuousStates fmi2GetNominalsOfContinuousStates
""".split()

# The state vectors (derivation.md of each model) and the number of event indicators.
STATES = {
    "second_order": (["q", "q_dot"], 0),
    "mass_spring_damper": (["x", "v"], 0),
    "pendulum": (["theta", "omega"], 0),
    "bumper": (["x", "x_mass", "v_mass"], 1),
    "quarter_car": (["z_s", "z_u", "z_r", "z_s_dot", "z_u_dot"], 0),
    "crank_slider": (["theta", "r1", "theta3", "r1_dot", "theta3_dot"], 1),
    "offset_crank_slider": (["theta", "r1", "theta3", "r1_dot", "theta3_dot"], 1),
    "crank_rocker": (["theta", "theta3", "theta4", "theta3_dot", "theta4_dot"], 1),
    "double_rocker": (["theta", "theta3", "theta4", "theta3_dot", "theta4_dot"], 1),
    "inverted_crank_slider": (["theta2", "r3", "theta3", "r3_dot", "theta3_dot"], 0),
    "trebuchet": (["theta1", "theta2", "theta3", "omega1", "omega2", "omega3", "x_p", "y_p", "vx_p", "vy_p"], 3),
    "road": (["x"], 2),  # the bump's two edges, where z_r'' jumps
}

SLIDER = {"der(theta)": "", "der(r1)": "r1_dot", "der(theta3)": "theta3_dot",
          "der(r1_dot)": "theta theta3 theta3_dot", "der(theta3_dot)": "theta theta3 theta3_dot"}
FOUR_BAR = {"der(theta)": "", "der(theta3)": "theta3_dot", "der(theta4)": "theta4_dot",
            "der(theta3_dot)": "theta theta3 theta4 theta3_dot theta4_dot",
            "der(theta4_dot)": "theta theta3 theta4 theta3_dot theta4_dot"}
TREBUCHET_RATES = "theta1 theta2 theta3 omega1 omega2 omega3"
# What each derivative depends on in continuous time (states, inputs, time), read off the
# equations of motion in derivation.md, over every regime of the hybrid models.
DERIVATIVES = {
    "second_order": {"der(q)": "q_dot", "der(q_dot)": "time q q_dot"},
    "mass_spring_damper": {"der(x)": "v", "der(v)": "F x v"},
    # c omega / (m L^2) is there for any friction c, though the default c is 0.
    "pendulum": {"der(theta)": "omega", "der(omega)": "theta omega"},
    # In contact x' = v_mass, v_mass' = -(K x + B v_mass)/M; separated x' = -(K/B) x, v_mass' = 0.
    "bumper": {"der(x)": "x v_mass", "der(x_mass)": "v_mass", "der(v_mass)": "x v_mass"},
    "quarter_car": {"der(z_s)": "z_s_dot", "der(z_u)": "z_u_dot", "der(z_r)": "time z_r_dot_ext",
                    "der(z_s_dot)": "z_s z_u z_s_dot z_u_dot",
                    "der(z_u_dot)": "time z_r_dot_ext z_s z_u z_r z_s_dot z_u_dot"},
    "crank_slider": SLIDER,
    "offset_crank_slider": SLIDER,
    "crank_rocker": FOUR_BAR,
    "double_rocker": FOUR_BAR,
    "inverted_crank_slider": {"der(theta2)": "", "der(r3)": "r3_dot", "der(theta3)": "theta3_dot",
                              "der(r3_dot)": "theta2 r3 theta3 r3_dot theta3_dot",
                              "der(theta3_dot)": "theta2 r3 theta3 r3_dot theta3_dot"},
    # Regime 1: every angle turns at omega1 and every rate has the same acceleration, a function
    # of the angles; regime 3: Lagrange's equations in all six; regime 4: free flight.
    "trebuchet": {"der(theta1)": "omega1", "der(theta2)": "omega1 omega2", "der(theta3)": "omega1 omega3",
                  "der(omega1)": TREBUCHET_RATES, "der(omega2)": TREBUCHET_RATES, "der(omega3)": TREBUCHET_RATES,
                  "der(x_p)": "vx_p", "der(y_p)": "vy_p", "der(vx_p)": "", "der(vy_p)": ""},
    # x' = speed, a parameter.
    "road": {"der(x)": ""},
}


def me(model, **kwargs):
    return simulate_fmu(str(fmu_path(model)), fmi_type="ModelExchange", **kwargs)


def test_every_fmu_declares_model_exchange_with_the_same_binary(any_fmu, tmp_path):
    md = read_model_description(str(any_fmu))
    model = md.coSimulation.modelIdentifier
    assert md.modelExchange is not None and md.modelExchange.modelIdentifier == model
    assert md.modelExchange.needsCompletedIntegratorStep
    assert md.modelExchange.canGetAndSetFMUstate and md.modelExchange.canSerializeFMUstate
    states, indicators = STATES[model]
    assert [d.variable.derivative.name for d in md.derivatives] == states
    assert md.numberOfEventIndicators == indicators
    assert md.numberOfContinuousStates == len(states)
    lib = ctypes.CDLL(f"{extract(str(any_fmu), unzipdir=str(tmp_path / 'fmu'))}/binaries/linux64/{model}.so")
    assert [name for name in FMI2_ME_FUNCTIONS if not hasattr(lib, name)] == []


def test_derivatives_declare_the_dependencies_of_the_equations(any_fmu):
    md = read_model_description(str(any_fmu))
    declared = {d.variable.name: sorted(v.name for v in d.dependencies) for d in md.derivatives}
    expected = {k: sorted(v.split()) for k, v in DERIVATIVES[md.coSimulation.modelIdentifier].items()}
    assert declared == expected


def test_initial_unknowns_declare_what_initialization_reads():
    """The bumper's initial values (derivation.md): x = x_mass = 0 whatever the parameters,
    v_mass = v = V0, a = -(B V0)/M (K x vanishes at x = 0), F_contact = B V0; and the quarter
    car's road rate at the start time, a omega cos(omega t) + z_r_dot_ext."""
    def initial(model):
        md = read_model_description(str(fmu_path(model)))
        return {u.variable.name: sorted(v.name for v in u.dependencies) for u in md.initialUnknowns}
    b = initial("bumper")
    assert (b["x"], b["x_mass"], b["in_contact"], b["t_release"]) == ([], [], [], [])
    assert b["v_mass"] == b["v"] == b["der(x)"] == ["V0"]
    assert b["a"] == b["der(v_mass)"] == ["B", "M", "V0"]
    assert b["F_contact"] == ["B", "V0"]
    q = initial("quarter_car")
    assert q["z_r_dot"] == sorted(["time", "speed", "road_amplitude", "road_wavelength", "z_r_dot_ext"])
    assert q["z_s"] == [] and q["n_rhs"] == []


@pytest.mark.usefixtures("fmi_version")
def test_second_order_matches_the_closed_form():
    r = me("second_order", relative_tolerance=1e-11, output_interval=0.01)
    t = r["time"]
    q, q_dot = reference("second_order", "q")(t=t), reference("second_order", "q_dot")(t=t)
    # CVODE at rtol = atol = 1e-11 on values of size ~2 (measured 1.2e-10 and 3.9e-10): bound
    # 1e-8, as for CS.
    assert np.max(np.abs(r["q"] - q)) < 1e-8
    assert np.max(np.abs(r["q_dot"] - q_dot)) < 1e-8


@pytest.mark.usefixtures("fmi_version")
def test_mass_spring_damper_step_force_from_fmpy_input():
    lbf, inch = 4.4482216152605, 0.0254
    k, m, b = 10 * lbf / inch, 2 * lbf / inch, lbf / inch
    f0 = 100.0
    signals = np.array([(0.0, f0), (10.0, f0)], dtype=[("time", np.float64), ("F", np.float64)])
    r = me("mass_spring_damper", relative_tolerance=1e-12, output_interval=0.01, input=signals)
    t = r["time"]
    # From rest under a constant f0: the free vibration about the shifted equilibrium f0/k.
    x = f0 / k + reference("mass_spring_damper", "x")(t=t, m=m, b=b, k=k, x0=-f0 / k, v0=0.0)
    # Response ~0.057 m; CVODE at rtol = atol = 1e-12 (measured 8e-11): bound 1e-9, as for CS.
    assert np.max(np.abs(r["x"] - x)) < 1e-9


@pytest.mark.usefixtures("fmi_version")
def test_pendulum_period_matches_the_elliptic_integral():
    L, g, m = 0.75, 9.81, 0.5
    ref = references("pendulum")
    for deg in (15.0, 120.0):
        theta0 = np.radians(deg)
        r = me("pendulum", relative_tolerance=1e-11, output_interval=1e-3, start_values={"theta0": theta0},
               output=["theta", "omega", "energy"])
        period = ref["period"](L=L, g=g, theta0=theta0)
        tc = zero_crossings(r["time"], r["theta"], r["omega"])
        n = np.arange(len(tc))
        assert len(tc) >= 8
        # Measured 4.5e-10 s (15 deg) and 2.5e-9 s (120 deg) at rtol 1e-11: bound 1e-8 s, as for CS.
        np.testing.assert_allclose(tc, period / 4 + n * period / 2, rtol=0, atol=1e-8)
        # BDF does not conserve energy as well as DOPRI5 at 1e-11 on 1 ms steps (measured
        # 1.8e-8 relative): bound 1e-7.
        e0 = ref["energy"](m=m, g=g, L=L, theta0=theta0)
        assert np.max(np.abs(r["energy"] - e0)) < 1e-7 * e0


BUMPER = dict(M=1000.0, K=9850.0, B=12500.0, V0=1.0)


@pytest.mark.usefixtures("fmi_version")
def test_bumper_releases_at_the_closed_form_time():
    ref, K, B = references("bumper"), BUMPER["K"], BUMPER["B"]
    r = me("bumper", relative_tolerance=1e-11, output_interval=1e-3, record_events=False,
           output=["x", "v", "a", "x_mass", "v_mass", "in_contact", "t_release"])
    t_r = ref["t_release"](**BUMPER)
    # CVODE locates the root of the contact force to its time tolerance; the release time is
    # off by the states' error over the root's slope (measured 2.0e-9 s at rtol 1e-11): 1e-8 s.
    assert abs(r["t_release"][-1] - t_r) < 1e-8
    t = r["time"]
    before, after = t < t_r, t > t_r
    assert np.all(r["in_contact"][before]) and not np.any(r["in_contact"][after])
    x_c, v_c = ref["x_contact"](t=t[before], **BUMPER), ref["v_contact"](t=t[before], **BUMPER)
    # Measured 1.8e-11 m and 2.1e-10 m/s: bounds 1e-10 and 1e-9.
    np.testing.assert_allclose(r["x"][before], x_c, rtol=0, atol=1e-10)
    np.testing.assert_allclose(r["v"][before], v_c, rtol=0, atol=1e-9)
    # After the release: the release time's error times |x'| and |v_r| adds ~1e-10 (measured
    # 1.3e-10 and 2.0e-10): bound 1e-9.
    np.testing.assert_allclose(r["x"][after], ref["x_separated"](t=t[after], **BUMPER), rtol=0, atol=1e-9)
    np.testing.assert_allclose(r["x_mass"][after], ref["x_mass_separated"](t=t[after], **BUMPER), rtol=0, atol=1e-9)
    np.testing.assert_allclose(r["a"][after], (K / B) ** 2 * r["x"][after], rtol=1e-12, atol=0)


@pytest.mark.usefixtures("fmi_version")
def test_attached_bumper_keeps_contact():
    r = me("bumper", relative_tolerance=1e-11, output_interval=1e-2, start_values={"attached": True},
           output=["x", "in_contact", "t_release", "F_contact"])
    assert np.all(r["in_contact"]) and np.all(r["t_release"] == -1.0)
    np.testing.assert_allclose(r["x"], references("bumper")["x_contact"](t=r["time"], **BUMPER), rtol=0, atol=1e-10)
    assert r["F_contact"][-1] < 0, "the fastened plate pulls the mass back"


@pytest.mark.usefixtures("fmi_version")
def test_quarter_car_transmissibility_at_body_resonance():
    car = dict(m_s=200.0, m_u=30.0, k_s=18000.0, b_s=1300.0, k_t=125000.0, b_t=10.0, road_wavelength=3.0)
    speed = 4.25
    r = me("quarter_car", relative_tolerance=1e-10, output_interval=1e-4, start_values={"speed": speed},
           output=["z_s", "z_r"])
    H = references("quarter_car")["transmissibility"](speed=speed, **car)
    late = r["time"] >= 7.0
    measured = np.max(r["z_s"][late]) / np.max(r["z_r"][late])
    # As for CS: transients below 2e-8 after 7 s, sampling 1e-7; CVODE's error at rtol 1e-10
    # on signals of 0.04 m is below 1e-7 relative (measured 2.7e-8 off |H| in all): 1e-5 bounds
    # the sum.
    assert abs(measured / H - 1) < 1e-5


def _cs_launch(tmp_path):
    """The trebuchet's Co-Simulation range, at the same tolerance."""
    r = simulate_fmu(str(fmu_path("trebuchet")), fmi_type="CoSimulation", relative_tolerance=1e-10, output_interval=1e-3,
                     start_values={"abs_tol": 1e-12}, output=["range"])
    return r["range"][-1]


def test_trebuchet_lands_where_its_co_simulation_lands(tmp_path):
    """The four regimes under CVODE: the impact and the release are state events in whose event
    mode the FMU resets the velocities (valuesOfContinuousStatesChanged), and the landing ends
    the run with terminateSimulation. fmpy records no row after that last event, so the range
    is read from the terminated instance."""
    md = read_model_description(str(fmu_path("trebuchet")))
    unzipdir = extract(str(fmu_path("trebuchet")), unzipdir=str(tmp_path / "treb"))
    fmu = instantiate_fmu(unzipdir, md, fmi_type="ModelExchange")
    r = simulate_fmu(unzipdir, fmi_type="ModelExchange", relative_tolerance=1e-10, output_interval=1e-3,
                     fmu_instance=fmu, output=["regime", "E_y", "misfire"])
    vr = {v.name: v.valueReference for v in md.modelVariables}
    rng, t_landing = fmu.getReal([vr["range"], vr["t_release"]])
    fmu.freeInstance()
    assert set(np.unique(r["regime"])) == {1, 3, 4} and np.all(np.diff(r["regime"]) >= 0)
    assert not r["misfire"][-1] and 2.0 < r["time"][-1] < 10.0
    cs = _cs_launch(tmp_path)
    # The release times differ by 2.9e-9 s at these tolerances (CVODE against the FMU's
    # DOPRI5); the landing point moves by that times |v| ~ 12 m/s plus the swing's integration
    # error: measured 3.4e-7 m, bound 1e-6 m (of a 23.2 m range).
    assert abs(rng - cs) < 1e-6, (rng, cs)
    assert 0 < t_landing < r["time"][-1]


@pytest.mark.usefixtures("fmi_version")
def test_offset_crank_slider_reaches_its_limit_position():
    p = defaults("offset_crank_slider")
    r = me("offset_crank_slider", relative_tolerance=1e-9, output_interval=0.01, output=["theta", "r1", "theta3", "loop_residual"])
    theta = p["theta0"] + p["omega"] * r["time"]
    # The stop is a state event of the exact crank angle (|cos theta3| = 0.05 on the loop,
    # references.toml's theta_stop, 0.0925 deg short of the limit); terminateSimulation ends
    # the run there: the last row is at theta_stop to CVODE's root location (bound 1e-8 rad).
    assert r["time"][-1] < 2.0 and abs(closed("offset_crank_slider", "theta_stop") - theta[-1]) < 1e-8
    r1, th3 = (closed("offset_crank_slider", name, theta=theta) for name in ("r1", "theta3"))
    ok = np.cos(th3) > 0.2
    # The drift is projected at step events when it exceeds rtol times the links' length, as
    # fmpy reports completed steps once per output interval; in between CVODE's own error grows
    # like powers of 1/cos(theta3) towards the limit. Measured where cos(theta3) > 0.2: 7.7e-8 m,
    # 7.0e-7 rad, a gap of 1.9e-8 m; bounds 5e-7 m, 5e-6 rad and 2e-7 m.
    assert np.max(np.abs(r["r1"][ok] - r1[ok])) < 5e-7
    assert np.max(np.abs(wrap(r["theta3"][ok] - th3[ok]))) < 5e-6
    assert np.max(r["loop_residual"][ok]) < 2e-7


@pytest.mark.usefixtures("fmi_version")
def test_double_rocker_reaches_its_limit_position():
    p = defaults("double_rocker")
    stop = closed("double_rocker", "theta_stop")
    for branch in (1, -1):
        r = me("double_rocker", relative_tolerance=1e-9, output_interval=0.01, start_values={"branch": branch},
               output=["theta", "theta3", "theta4"])
        theta = p["theta0"] + p["omega"] * r["time"]
        # As for the offset crank-slider: |sin(theta4 - theta3)| = 0.05 on the loop.
        assert r["time"][-1] < 2.0 and abs(stop - theta[-1]) < 1e-8
        th3, th4 = (closed("double_rocker", name, theta=theta, branch=branch) for name in ("theta3", "theta4"))
        ok = np.abs(np.sin(th4 - th3)) > 0.2
        # As for the offset crank-slider (measured 4.6e-7 rad where |sin(theta4 - theta3)| >
        # 0.2): bound 5e-6 rad.
        assert np.max(np.abs(wrap(r["theta3"][ok] - th3[ok]))) < 5e-6
        assert np.max(np.abs(wrap(r["theta4"][ok] - th4[ok]))) < 5e-6


# Each model's input angle, its start and the two outputs its closed form gives.
FULL_TURN = {
    "crank_slider": ("theta", "theta0", ("r1", "theta3")),
    "crank_rocker": ("theta", "theta0", ("theta3", "theta4")),
    "inverted_crank_slider": ("theta2", "theta2_0", ("r3", "theta3")),
}


@pytest.mark.usefixtures("fmi_version")
@pytest.mark.parametrize("model", sorted(FULL_TURN))
def test_full_turn_linkages_follow_their_closed_forms(model):
    r = me(model, relative_tolerance=1e-10, output_interval=0.01)
    t = r["time"]
    p, (angle, start, outputs) = defaults(model), FULL_TURN[model]
    # The default experiments: two revolutions.
    assert t[-1] == pytest.approx(4 * np.pi / abs(p["omega"]))
    inputs = {angle: p[start] + p["omega"] * t}
    errors = [np.abs(wrap(r[name] - closed(model, name, **inputs))) for name in outputs]
    # Loop closure projected at step events (a drift above rtol 1e-10 of the lengths, checked
    # at every output point) and CVODE's error over 2 to 24 s of a periodic motion (measured
    # 6.2e-8 at most, loop gaps 2e-8 m): bounds 2e-7 and 1e-7 m.
    assert max(np.max(e) for e in errors) < 2e-7
    assert np.max(r["loop_residual"]) < 1e-7


@pytest.mark.usefixtures("fmi_version")
@pytest.mark.parametrize("model", MODELS)
def test_default_model_exchange_run_through_fmpy_is_finite(model):
    md = read_model_description(str(fmu_path(model)))
    r = me(model)
    assert r["time"][-1] > 0
    assert r["time"][-1] == pytest.approx(float(md.defaultExperiment.stopTime)) or model in (
        "offset_crank_slider", "double_rocker", "trebuchet")
    for name in r.dtype.names:
        assert np.all(np.isfinite(r[name].astype(float))), name
