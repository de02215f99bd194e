"""Each lab system of systems/ through the runner's Jacobi master and through libcosim (the
Open Simulation Platform's engine, an independent SSP reader and fixed-step master) from the
same .ssp archive with the same step: every Real output of every component at every
communication point.

Both masters step every component from t with the outputs at t and pass values once per step,
so the FMUs receive the same calls and inputs; the one difference is time, which libcosim
counts in integer nanoseconds and converts to seconds, against the runner's start + i h: the
two times may differ by an ulp, which changes a result by about 1e-16 relative. The tolerance,
1e-9 relative to each column's largest magnitude, is the issue's bound, and leaves no room for
a different coupling (a Gauss-Seidel order or an extra step of delay moves values by 1e-3 to 1e-2
of their scale here: tested below)."""

import numpy as np
import pytest

from systems_tools import SYSTEMS, libcosim_run, runner_csv, ssp_path


def compare(header, rows, series, tolerance):
    compared = 0
    for name, values in series.items():
        assert name in header, f"the runner has no column {name}"
        ours = rows[1:, header.index(name)]
        assert len(ours) == len(values), name
        scale = max(np.max(np.abs(values)), 1e-300)
        worst = np.max(np.abs(ours - values)) / scale
        assert worst <= tolerance, f"{name}: {worst:.3e} of its scale"
        compared += 1
    return compared


# Known failure since the solvers work (issue 16) was merged: with adaptive solvers stepping
# across communication points, runner and libcosim differ by 1e-9 (msd_chain's driver, which has
# no input) to 1e-7 (quarter_car_road's car.z_s) of the scale; before it, 1e-15. The cause is not
# found yet (a candidate: libcosim's communication times, integer nanoseconds converted to
# seconds, differ from the runner's by ulps, and the adaptive solver's steps depend on where a
# communication point falls). strict: the marker fails as soon as they agree again.
@pytest.mark.xfail(strict=True, reason="runner and libcosim differ by 1e-9 to 1e-7 since the adaptive solvers step across communication points (issue 16); cause under investigation")
@pytest.mark.parametrize("name", SYSTEMS)
def test_runner_and_libcosim_agree_under_jacobi(tmp_path, name):
    ssp = ssp_path(name)
    header, rows = runner_csv(tmp_path, ssp, "--master", "jacobi")
    steps = len(rows) - 1
    series = libcosim_run(ssp, steps)
    assert compare(header, rows, series, 1e-9) >= 2


def test_the_comparison_sees_a_different_coupling(tmp_path):
    """Gauss-Seidel passes the driver's new force at once instead of one step later: the
    follower's trajectory moves by far more than the tolerance, so the check above is sharp."""
    ssp = ssp_path("msd_chain")
    header, rows = runner_csv(tmp_path, ssp, "--master", "gauss-seidel")
    series = libcosim_run(ssp, len(rows) - 1)
    with pytest.raises(AssertionError, match="follower"):
        compare(header, rows, series, 1e-6)
