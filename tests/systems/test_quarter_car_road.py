"""The quarter car driven by the road FMU (systems/quarter_car_road: road.z_r_dot ->
car.z_r_dot_ext, the car's own road off) against the car on its built-in road (the Ex. 4 sweep),
at rtol 1e-9 and the Ex. 4 step h = 1 ms, under each coupling.

Hold (`--coupling hold`): the system holds the road rate over each communication step at its
value at the step's start. The car integrates that held rate into its z_r: summing
h a w cos(w t_k) gives g a sin(w t - w h / 2) + g a sin(w h / 2), g = (w h / 2) / sin(w h / 2) =
1 + O((w h)^2): the built-in road delayed by h / 2 and raised by eps a, eps = w h / 2 =
pi v h / wavelength (0.1 % of the amplitude at 1 m/s, 5.2 % at 50 m/s). The raise is a static
offset, which z_s follows with gain 1, so in the steady state max(z_s)/max(z_r) =
(T a + eps a)/(a + eps a) = (T + eps)/(1 + eps) for the built-in road's T. The whole-run maximum
(set by the start-up transient above 5 m/s) moves by at most eps (1 + T): max(z_r) by eps a,
max(z_s) by eps a.

Polynomial (`--coupling polynomial`, the default here): the road FMU gives z_r_dot's time
derivatives (orders 1 to 3, exact) and the car interpolates its input. Under Jacobi the car's
input is the cubic Taylor polynomial at the step's start: its error over a step is
a w^5 h^4 / 24 at most, and summed over the steps it offsets z_r by about (w h)^5 a / 240
(the first order whose sum does not vanish at t = 0), 5e-8 a at 50 m/s, 1.5e-6 of the
steady-state T there. Under Gauss-Seidel the road steps first and the car's input is the cubic
Hermite interpolant of the rate's values and slopes at both ends of the step, smaller still. The
issue's target is 1e-4 relative at every speed from 1 to 50 m/s, for both masters; measured
1.0e-6 (Jacobi, steady state at 50 m/s) and 1.4e-8 (Gauss-Seidel)."""

import csv
import math

import pytest

from systems_tools import runner, ssp_path

SPEEDS = "1,2,4,7,10,20,30,50"
METRICS = ["--metric", "whole=max(z_s)/max(z_r)", "--metric", "steady=max(z_s, 5)/max(z_r, 5)"]


def sweep(tmp_path, target, param, prefix="", speeds=SPEEDS, extra=()):
    out = tmp_path / f"{param}{'_'.join(extra)}.csv"
    metrics = [m.replace("z_", f"{prefix}z_") if m != "--metric" else m for m in METRICS]
    done = runner("sweep", target, "--param", f"{param}={speeds}", *metrics, "--tolerance", "1e-9", "--threads", "2",
                  "--out", out, *extra)
    assert done.returncode == 0, done.stderr
    with open(out) as f:
        return list(csv.DictReader(f))


def test_the_road_fmu_reproduces_the_built_in_road_up_to_the_hold(tmp_path):
    system = sweep(tmp_path, ssp_path("quarter_car_road"), "road.speed", "car.", extra=("--coupling", "hold"))
    builtin = sweep(tmp_path, "quarter_car", "speed")
    assert len(system) == len(builtin) == 8
    for s, b in zip(system, builtin):
        v = float(s["road.speed"])
        assert v == float(b["speed"]) and s["status"] == "ok"
        eps = math.pi * v * 1e-3 / 3
        steady, whole = float(b["steady"]), float(b["whole"])
        # The hold's prediction, to 5 % of the change it makes (the O((w h)^2) terms and the
        # transient left in the last 5 s at 1 m/s account for the rest: measured 0.8 % at most).
        predicted = (steady + eps) / (1 + eps)
        assert abs(float(s["steady"]) - predicted) <= 0.05 * eps * abs(1 - steady), (v, s["steady"], predicted)
        assert abs(float(s["whole"]) - whole) <= eps * (1 + whole), (v, s["whole"], whole)


@pytest.mark.parametrize("master", ["jacobi", "gauss-seidel"])
def test_polynomial_coupling_meets_the_monolithic_car_to_1e_4(tmp_path, master):
    """Every speed from 1 to 50 m/s: the whole-run and the steady-state transmissibility within
    1e-4 relative of the built-in road's (the hold misses the steady state by 146 % at 50 m/s)."""
    speeds = "1:50:1"
    system = sweep(tmp_path, ssp_path("quarter_car_road"), "road.speed", "car.", speeds,
                   ("--master", master, "--coupling", "polynomial"))
    builtin = sweep(tmp_path, "quarter_car", "speed", speeds=speeds)
    assert len(system) == len(builtin) == 50
    for s, b in zip(system, builtin):
        v = float(s["road.speed"])
        assert v == float(b["speed"]) and s["status"] == "ok"
        for metric in ("whole", "steady"):
            ours, theirs = float(s[metric]), float(b[metric])
            assert abs(ours - theirs) <= 1e-4 * abs(theirs), (master, v, metric, ours, theirs)


def test_the_default_coupling_is_polynomial_here(tmp_path):
    """Both ends of the one connection allow it, so no flag means polynomial: the same numbers."""
    default = sweep(tmp_path, ssp_path("quarter_car_road"), "road.speed", "car.", "30,50")
    chosen = sweep(tmp_path, ssp_path("quarter_car_road"), "road.speed", "car.", "30,50", ("--coupling", "polynomial"))
    assert default == chosen


def test_an_fmi3_road_drives_the_fmi2_car_polynomially(tmp_path):
    """The road as an FMI 3.0 FMU (fmi3GetOutputDerivatives) driving the FMI 2.0 car: the same
    coupling, the same 1e-4 at 50 m/s under both masters (FMI 3.0 has no input derivatives,
    so only the source may be FMI 3.0 here)."""
    import shutil

    from systems_tools import ROOT, TARGET

    folder = tmp_path / "mixed"
    (folder / "resources").mkdir(parents=True)
    for f in (ROOT / "systems" / "quarter_car_road").iterdir():
        shutil.copy(f, folder)
    shutil.copy(TARGET / "fmu3" / "road.fmu", folder / "resources" / "road.fmu")
    shutil.copy(TARGET / "fmu" / "quarter_car.fmu", folder / "resources" / "quarter_car.fmu")
    builtin = sweep(tmp_path, "quarter_car", "speed", speeds="50")
    for master in ("jacobi", "gauss-seidel"):
        system = sweep(tmp_path, folder, "road.speed", "car.", "50", ("--master", master))
        for metric in ("whole", "steady"):
            ours, theirs = float(system[0][metric]), float(builtin[0][metric])
            assert abs(ours - theirs) <= 1e-4 * abs(theirs), (master, metric, ours, theirs)


def with_road_orders(tmp_path, orders):
    """systems/quarter_car_road with a copy of the road FMU whose modelDescription offers
    output derivatives up to `orders` only (maxOutputDerivativeOrder; the binary is the same)."""
    import shutil
    import zipfile

    from systems_tools import ROOT, TARGET

    folder = tmp_path / f"orders{orders}"
    (folder / "resources").mkdir(parents=True)
    for f in (ROOT / "systems" / "quarter_car_road").iterdir():
        shutil.copy(f, folder)
    shutil.copy(TARGET / "fmu" / "quarter_car.fmu", folder / "resources" / "quarter_car.fmu")
    with zipfile.ZipFile(TARGET / "fmu" / "road.fmu") as src, \
            zipfile.ZipFile(folder / "resources" / "road.fmu", "w", zipfile.ZIP_DEFLATED) as dst:
        for item in src.infolist():
            data = src.read(item)
            if item.filename == "modelDescription.xml":
                text = data.decode()
                assert 'maxOutputDerivativeOrder="3"' in text
                data = text.replace('maxOutputDerivativeOrder="3"', f'maxOutputDerivativeOrder="{orders}"').encode()
            dst.writestr(item, data)
    return folder


def test_a_source_with_fewer_output_derivatives_gets_a_lower_order(tmp_path):
    """The road offering orders 0 to 3 (maxOutputDerivativeOrder), at 50 m/s, where the hold
    misses the steady state most. Jacobi extrapolates the Taylor polynomial of the orders the
    source offers: 0 is the hold (bit for bit), 3 the default (bit for bit). The car integrates
    its input into z_r, so order k offsets z_r by the sum of the per-step misses,
    h^(k+1) (u^(k)(t) - u^(k)(0)) / (k+2)! for u = a w cos(w t), w h = 0.1: order 1 a
    quadrature term of relative size (w h)^2 / 6 = 1.7e-3 (it moves the maxima little), order 2 a
    static raise (w h)^3 / 24 = 4e-5 of a, which z_s follows with gain 1, 1.2e-3 of the small
    T = 0.033 at 50 m/s; order 3 what the README gives, 1e-6. Measured: 1.46, 1.40e-3, 1.40e-3,
    1.0e-6. So the test asks: orders 1 and 2 remove the hold's error but for 1 %, order 3 for
    1e-5, and orders 1 and 2 differ (the master passes what the source offers). Gauss-Seidel's
    cubic through both ends needs the first derivative alone: order 1 already gives the
    default's numbers, bit for bit."""
    builtin = float(sweep(tmp_path, "quarter_car", "speed", speeds="50")[0]["steady"])
    errors = []
    for orders in range(4):
        folder = with_road_orders(tmp_path, orders)
        jacobi = sweep(tmp_path, folder, "road.speed", "car.", "50", ("--master", "jacobi"))[0]
        errors.append(abs(float(jacobi["steady"]) - builtin) / builtin)
        if orders == 0:
            hold = sweep(tmp_path, folder, "road.speed", "car.", "50", ("--master", "jacobi", "--coupling", "hold"))[0]
            assert jacobi["steady"] == hold["steady"], (jacobi, hold)
        if orders == 1:
            gs = sweep(tmp_path, folder, "road.speed", "car.", "50", ("--master", "gauss-seidel"))[0]
            gs_full = sweep(tmp_path, ssp_path("quarter_car_road"), "road.speed", "car.", "50", ("--master", "gauss-seidel"))[0]
            assert gs["steady"] == gs_full["steady"], (gs, gs_full)
    default = sweep(tmp_path, ssp_path("quarter_car_road"), "road.speed", "car.", "50", ("--master", "jacobi"))[0]
    assert abs(float(default["steady"]) - builtin) / builtin == errors[3]
    print("relative steady-state error at 50 m/s by the road's maxOutputDerivativeOrder 0..3:", errors)
    assert errors[0] > 1
    assert errors[1] < 0.01 * errors[0] and errors[2] < 0.01 * errors[0], errors
    assert errors[1] != errors[2], errors
    assert errors[3] < 1e-5 * errors[0], errors
