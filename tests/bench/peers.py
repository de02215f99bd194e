"""Python peers for the quarter-car sweep benchmark (handbook Ex. 4).

Every peer runs the same experiment as `runner sweep quarter_car`: one run per road speed,
relative tolerance 1e-9, stop time 10 s, samples every 1e-3 s (10001 samples, t = 0 included),
and the metric transmissibility = max(z_s) / max(z_r) over all samples of the run. Each peer
prints one JSON object on stdout: the wall time of the whole sweep, the wall time per run and
the metric per speed, so the cost per run can be compared and the numbers checked against the
runner's CSV.

    fmpy   The toolkit's own FMU driven by fmpy.simulate_fmu (Co-Simulation), the usual way a
           Python user runs an FMU. Same binary and same DOPRI5 as the runner, so the metric
           agrees to rounding; the difference is the cost of driving 10000 doStep calls from
           Python. With --processes N the speeds go to a multiprocessing Pool of N worker
           processes; the pool's start-up is part of the measured time.
    scipy  The model's five equations ported by hand to a plain-Python rhs(t, y) and solved by
           scipy.integrate.solve_ivp(method='RK45'), a Dormand-Prince 5(4) like the FMU's default
           solver, at the FMU's tolerances (rtol 1e-9, atol = the FMU's abs_tol 1e-9), one speed
           after another: what a student porting the lab to Python would write. Also reports
           its right-hand-side evaluations (nfev) per speed.
    reference  Not timed: per speed, scipy's RK45 as above (its nfev and transmissibility) and
           scipy's DOP853 at rtol 1e-12 (atol 1e-14), the accuracy reference, in a Pool of
           --processes worker processes.

Fairness: every peer does the same work per run (same equations, method family, tolerances,
horizon and sampling) and is set up the way a sensible user sets it up: fmpy unzips the FMU
once per sweep and parses modelDescription.xml once per process, not once per run; the scipy
port has no per-run setup beyond building its parameters. Set-up paid once is still inside
wall_seconds. The adaptive solvers take more steps at higher speeds (more road periods in
10 s), so compare peers on the same list of speeds.

Usage:
    python peers.py fmpy --fmu target/fmu/quarter_car.fmu --speeds 1,5,10,20 [--processes 2]
    python peers.py scipy --speeds 1,5,10
    python peers.py reference --speeds 1,1.5,2 [--processes 2]
"""

import argparse
import json
import math
import multiprocessing
import shutil
import sys
import time

import numpy as np

STOP_TIME = 10.0
OUTPUT_INTERVAL = 1e-3
RTOL = 1e-9
ATOL = 1e-9  # the FMU's abs_tol default

# Table 4.1 and the road of models/quarter_car (the FMU's start values).
PARAMS = dict(m_s=200.0, m_u=30.0, k_s=18000.0, b_s=1300.0, k_t=125000.0, b_t=10.0,
              road_amplitude=0.04, road_wavelength=3.0)


# ---------------------------------------------------------------------------------------------
# fmpy peer

# Per-process state: the extracted FMU directory, its parsed model description, the interface.
_FMU_DIR = None
_MODEL_DESCRIPTION = None
_FMI_TYPE = 'CoSimulation'


def _fmpy_init(fmu_dir, fmi_type='CoSimulation'):
    """Once per process: read modelDescription.xml of the already-extracted FMU, as an fmpy user
    running many simulations of one FMU would (simulate_fmu would otherwise unzip the FMU and
    parse its model description again on every run)."""
    global _FMU_DIR, _MODEL_DESCRIPTION, _FMI_TYPE
    import fmpy
    _FMU_DIR = fmu_dir
    _MODEL_DESCRIPTION = fmpy.read_model_description(fmu_dir)
    _FMI_TYPE = fmi_type


def _fmpy_run(speed):
    """One run at `speed`: returns (speed, transmissibility)."""
    import fmpy
    result = fmpy.simulate_fmu(
        _FMU_DIR,
        model_description=_MODEL_DESCRIPTION,
        # ModelExchange: fmpy's CVODE (BDF) integrates through the FMU's derivatives.
        fmi_type=_FMI_TYPE,
        start_values={'speed': speed},
        stop_time=STOP_TIME,
        output_interval=OUTPUT_INTERVAL,
        relative_tolerance=RTOL,
        output=['z_s', 'z_r'],
    )
    return speed, float(np.max(result['z_s']) / np.max(result['z_r']))


def run_fmpy(fmu_path, speeds, processes, fmi_type='CoSimulation'):
    import fmpy
    start = time.perf_counter()
    # Unzip once for the whole sweep; every process loads the binary from this directory.
    fmu_dir = fmpy.extract(fmu_path)
    try:
        if processes == 1:
            # One process: no pool, the same per-process set-up done here.
            _fmpy_init(fmu_dir, fmi_type)
            results = [_fmpy_run(s) for s in speeds]
        else:
            # Each worker runs one FMU instance at a time; chunksize 1 balances uneven runs.
            with multiprocessing.Pool(processes, initializer=_fmpy_init, initargs=(fmu_dir, fmi_type)) as pool:
                results = pool.map(_fmpy_run, speeds, chunksize=1)
        wall = time.perf_counter() - start
    finally:
        shutil.rmtree(fmu_dir, ignore_errors=True)
    return report('fmpy', processes, speeds, results, wall)


# ---------------------------------------------------------------------------------------------
# scipy peer: models/quarter_car/derivation.md, state x = [z_s, z_u, z_r, z_s', z_u'],
# input u = z_r' = a omega cos(omega t), omega = 2 pi speed / wavelength; all states start at 0.

def make_rhs(speed, m_s, m_u, k_s, b_s, k_t, b_t, road_amplitude, road_wavelength):
    omega = 2.0 * math.pi * speed / road_wavelength
    a_omega = road_amplitude * omega

    def rhs(t, y):
        z_s, z_u, z_r, v_s, v_u = y
        u = a_omega * math.cos(omega * t)
        suspension = k_s * (z_s - z_u) + b_s * (v_s - v_u)
        tire = k_t * (z_u - z_r) + b_t * (v_u - u)
        return [v_s, v_u, u, -suspension / m_s, (suspension - tire) / m_u]

    return rhs


def _solve(speed, method, rtol, atol):
    """One 10 s run sampled every 1 ms: (transmissibility, right-hand-side evaluations)."""
    from scipy.integrate import solve_ivp
    t_eval = np.arange(10001) * OUTPUT_INTERVAL
    sol = solve_ivp(make_rhs(speed, **PARAMS), (0.0, STOP_TIME), [0.0] * 5, method=method,
                    t_eval=t_eval, rtol=rtol, atol=atol)
    if not sol.success:
        raise RuntimeError(f"speed {speed}: {sol.message}")
    return float(np.max(sol.y[0]) / np.max(sol.y[2])), int(sol.nfev)


def run_scipy(speeds):
    start = time.perf_counter()
    runs = [(s, _solve(s, 'RK45', RTOL, ATOL)) for s in speeds]
    wall = time.perf_counter() - start
    out = report('scipy_rk45', 1, speeds, [(s, tr) for s, (tr, _) in runs], wall)
    out['nfev'] = {f'{s:g}': n for s, (_, n) in runs}
    return out


# The accuracy reference: DOP853 (8th order) at a tolerance 1000x tighter than the sweep's.
REFERENCE_RTOL, REFERENCE_ATOL = 1e-12, 1e-14


def _reference_run(speed):
    rk45, nfev = _solve(speed, 'RK45', RTOL, ATOL)
    reference, _ = _solve(speed, 'DOP853', REFERENCE_RTOL, REFERENCE_ATOL)
    return speed, rk45, nfev, reference


def run_reference(speeds, processes):
    start = time.perf_counter()
    with multiprocessing.Pool(processes) as pool:
        runs = pool.map(_reference_run, speeds, chunksize=1)
    wall = time.perf_counter() - start
    return {
        'tool': 'scipy_reference',
        'processes': processes,
        'runs': len(speeds),
        'wall_seconds': wall,
        'rk45': {f'{s:g}': tr for s, tr, _, _ in runs},
        'nfev': {f'{s:g}': n for s, _, n, _ in runs},
        'dop853': {f'{s:g}': ref for s, _, _, ref in runs},
    }


# ---------------------------------------------------------------------------------------------

def report(tool, processes, speeds, results, wall):
    return {
        'tool': tool,
        'processes': processes,
        'runs': len(speeds),
        'wall_seconds': wall,
        'per_run_seconds': wall / len(speeds),
        'transmissibility': {f'{s:g}': v for s, v in results},
    }


def parse_speeds(text):
    speeds = [float(s) for s in text.split(',') if s.strip()]
    if not speeds:
        raise argparse.ArgumentTypeError('no speeds given')
    return speeds


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    sub = parser.add_subparsers(dest='tool', required=True)
    p = sub.add_parser('fmpy', help='the FMU through fmpy.simulate_fmu')
    p.add_argument('--fmu', required=True, help='path to quarter_car.fmu')
    p.add_argument('--speeds', required=True, type=parse_speeds, help='comma-separated speeds (m/s)')
    p.add_argument('--processes', type=int, default=1, help='worker processes (default 1)')
    p.add_argument('--fmi-type', default='CoSimulation', choices=['CoSimulation', 'ModelExchange'],
                   help='the interface fmpy drives (ModelExchange: its CVODE integrates)')
    p = sub.add_parser('scipy', help='hand port solved by scipy solve_ivp RK45')
    p.add_argument('--speeds', required=True, type=parse_speeds, help='comma-separated speeds (m/s)')
    p = sub.add_parser('reference', help='untimed: RK45 nfev and a DOP853 rtol 1e-12 reference per speed')
    p.add_argument('--speeds', required=True, type=parse_speeds, help='comma-separated speeds (m/s)')
    p.add_argument('--processes', type=int, default=2, help='worker processes (default 2)')
    args = parser.parse_args(argv)

    if args.tool in ('fmpy', 'reference') and args.processes < 1:
        parser.error('--processes must be at least 1')
    if args.tool == 'fmpy':
        out = run_fmpy(args.fmu, args.speeds, args.processes, args.fmi_type)
    elif args.tool == 'reference':
        out = run_reference(args.speeds, args.processes)
    else:
        out = run_scipy(args.speeds)
    json.dump(out, sys.stdout)
    sys.stdout.write('\n')


if __name__ == '__main__':
    main()
