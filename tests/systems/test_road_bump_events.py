"""Events between grid points: the quarter car driven over the road FMU's bump (profile 1),
against an independent reference.

The bump's edges are state events of the road FMU (z_r'' jumps there by (h/2)(2 pi/l)^2 v^2).
The FMI 3.0 road may return early from fmi3DoStep at them (earlyReturn); the master then
brings the car to the edge with a shorter step, passes the road's rate and its derivatives
there, and goes on. The FMI 2.0 road handles the same events inside its steps, which the master
sees only at the next grid point: the car's input polynomial of a step that contains an edge is
that of the other side of the edge (zero before the bump, the bump's cosine after it).

Reference: the car's five linear equations (handbook Ex. 4, models/quarter_car) with the bump's
rate in closed form, integrated by scipy's DOP853 at rtol 1e-12 piece by piece between the
edges (so no step crosses a kink), with the car FMU's own parameter values.

The speed, 7 m/s, puts both edges (5/7 s and 6/7 s) between the 1 ms grid points."""

import math
import shutil

import numpy as np
import pytest

from systems_tools import ROOT, TARGET, runner_csv

SPEED, STOP, STEP = 7.0, 2.0, 1e-3
BUMP_START, BUMP_LENGTH, BUMP_HEIGHT = 5.0, 1.0, 0.05  # road's defaults (models/road)


def system(tmp_path, road_fmi, car_fmi=2):
    """systems/quarter_car_road with the road of FMI version `road_fmi` (target/fmu or
    target/fmu3) and by default the FMI 2.0 car (FMI 3.0 has no input derivatives)."""
    folder = tmp_path / f"road{road_fmi}car{car_fmi}"
    (folder / "resources").mkdir(parents=True)
    for f in (ROOT / "systems" / "quarter_car_road").iterdir():
        shutil.copy(f, folder)
    version = {2: "fmu", 3: "fmu3"}
    shutil.copy(TARGET / version[road_fmi] / "road.fmu", folder / "resources" / "road.fmu")
    shutil.copy(TARGET / version[car_fmi] / "quarter_car.fmu", folder / "resources" / "quarter_car.fmu")
    return folder


def run(tmp_path, folder, master, coupling, step=STEP):
    header, rows = runner_csv(tmp_path, folder, "--set", "road.profile=1", "--set", f"road.speed={SPEED}",
                              "--stop-time", STOP, "--output-interval", step, "--tolerance", "1e-9",
                              "--master", master, "--coupling", coupling)
    return rows[:, 0], rows[:, header.index("car.z_s")], rows[:, header.index("car.z_u")]


def bump_rate(t):
    u = SPEED * t - BUMP_START
    k = 2 * math.pi / BUMP_LENGTH
    return SPEED * BUMP_HEIGHT / 2 * k * math.sin(k * u) if 0 <= u <= BUMP_LENGTH else 0.0


def reference(times):
    """z_s and z_u of the car on the bump at `times`."""
    from fmpy import read_model_description
    from scipy.integrate import solve_ivp

    md = read_model_description(str(TARGET / "fmu" / "quarter_car.fmu"))
    p = {v.name: float(v.start) for v in md.modelVariables if v.causality == "parameter"}
    m_s, m_u, k_s, b_s, k_t, b_t = (p[n] for n in ("m_s", "m_u", "k_s", "b_s", "k_t", "b_t"))

    def f(t, x):
        z_s, z_u, z_r, v_s, v_u = x
        u = bump_rate(t)
        suspension = k_s * (z_s - z_u) + b_s * (v_s - v_u)
        tire = k_t * (z_u - z_r) + b_t * (v_u - u)
        return [v_s, v_u, u, -suspension / m_s, (suspension - tire) / m_u]

    edges = [0.0, BUMP_START / SPEED, (BUMP_START + BUMP_LENGTH) / SPEED, STOP]
    out = np.empty((2, len(times)))
    x = np.zeros(5)
    for a, b in zip(edges, edges[1:]):
        sol = solve_ivp(f, (a, b), x, method="DOP853", rtol=1e-12, atol=1e-15, dense_output=True)
        assert sol.success
        inside = (times >= a) & (times <= b)
        out[:, inside] = sol.sol(times[inside])[:2]
        x = sol.y[:, -1]
    return out


def errors(tmp_path, folder, master, coupling, step=STEP):
    t, z_s, z_u = run(tmp_path, folder, master, coupling, step)
    ref = reference(t)
    return max(np.abs(z_s - ref[0]).max(), np.abs(z_u - ref[1]).max())


@pytest.mark.parametrize("master", ["jacobi", "gauss-seidel"])
def test_the_car_meets_the_bump_at_its_edges(tmp_path, master):
    """Polynomial coupling: with the FMI 3.0 road the master steps to each edge and what is
    left is the solvers' error and the cubic's own truncation inside the bump (Jacobi's Taylor
    cubic misses A w^4 h^5 / 120 = 3e-11 m per step with A = 1.1 m/s the bump's peak rate and
    w = 2 pi v / l = 44 rad/s, over its 143 steps 5e-9 m at most): measured 2.9e-9 m (Jacobi)
    and 1.7e-9 m (Gauss-Seidel) at rtol 1e-9, 0.9e-9 m and 1.1e-9 m at rtol 1e-11, so the bound
    is 1e-8 m (2e-7 of the bump's height). With the FMI 2.0 road the edges are met at the grid
    points and the error is the missed rate's integral over the part of a step beyond an edge,
    up to (h_b / 2) w^2 h^2 / 2 = 2.4e-5 m in z_r at h = 1 ms: O(h^2), halving the step divides
    it by about four (between 3 and 6: the edges' offsets inside their steps change with the
    step). Hold coupling: O(h) everywhere, with or without the events (half the step, half the
    error)."""
    fmi3, fmi2 = system(tmp_path, 3), system(tmp_path, 2)
    synchronized = errors(tmp_path, fmi3, master, "polynomial")
    on_the_grid = errors(tmp_path, fmi2, master, "polynomial")
    on_the_grid_half = errors(tmp_path, fmi2, master, "polynomial", STEP / 2)
    held = errors(tmp_path, fmi3, master, "hold")
    held_half = errors(tmp_path, fmi3, master, "hold", STEP / 2)
    print(f"{master}: synchronized {synchronized:.2e} m; events on the grid {on_the_grid:.2e} m "
          f"(half step {on_the_grid_half:.2e}); hold {held:.2e} m (half step {held_half:.2e})")
    assert synchronized < 1e-8, synchronized
    assert on_the_grid > 100 * synchronized, (on_the_grid, synchronized)
    assert 3 < on_the_grid / on_the_grid_half < 6, (on_the_grid, on_the_grid_half)
    assert 1.8 < held / held_half < 2.2, (held, held_half)


@pytest.mark.parametrize("master", ["jacobi", "gauss-seidel"])
def test_an_all_fmi3_system_meets_the_edges_as_the_mixed_one_does(tmp_path, master):
    """Both components FMI 3.0, coupled by the hold (FMI 3.0 sets no input derivatives): the road
    returns early at each edge and the FMI 3.0 car takes the shorter step to it, as the FMI 2.0
    car does in the mixed system (both cars are the same model and solver), so the two runs are
    the same to the bit; and not the run of the FMI 2.0 road, whose edges wait for the grid."""
    all3 = run(tmp_path, system(tmp_path, 3, car_fmi=3), master, "hold")
    mixed = run(tmp_path, system(tmp_path, 3), master, "hold")
    late = run(tmp_path, system(tmp_path, 2), master, "hold")
    for ours, theirs in zip(all3, mixed):
        np.testing.assert_array_equal(ours, theirs)
    assert np.abs(all3[1] - late[1]).max() > 1e-9
