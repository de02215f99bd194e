"""Every FMU of ours in every importer: how each importer runs one FMU, the runner's reference
for it, and how the two are compared.

A cell of the matrix is (importer, FMI version, interface, relative tolerance, model). Each run
must reach the model's stop time or its documented early end (a limit position, a landing: the
runner reports the time), and its outputs must agree with the runner's on the rows both have:
- Co-Simulation in fmpy: the FMU integrates itself with its own solver over the same
  communication points as in the runner, so the numbers are the same up to rounding (1e-9 of
  each output's range).
- Co-Simulation in a fixed-step master (libcosim, Ecos, fmi-sim, an FMU container): these add
  the step to the time (t + h) instead of computing k h, so the FMU's communication points
  differ in their last bits, its adaptive solver takes other steps, and the results differ
  within the FMU's tolerance (1e-6 of each output's range at its default rtol 1e-6).
- Model Exchange with fmpy's CVODE at rtol r: CVODE's global error is not bounded by r (it
  controls the local error per step, and errors grow along the run); against the runner's
  Co-Simulation at rtol 1e-10 (its own DOPRI5, whose error is below 1e-8 of the ranges) the
  agreement asked is 1000 r of each output's range, and no tighter than 1e-7 (the reference's
  own error, and CVODE's floor near the events these models have).
- Model Exchange in fmi-sim: its fixed-step explicit Euler at the output interval, so first
  order in the step; the agreement asked is 5 % of each output's range, which catches a wrong
  sign, a missed event or a wrong state but not the method's error.
"""

import csv
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
TARGET = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
RUNNER = TARGET / "release" / "runner"
TOLERANCES = [1e-4, 1e-6, 1e-8, 1e-10, 1e-12]
# Counters of the FMU's own solver, which differ by importer and interface by design, and the
# linkages' loop-closure residual, rounding noise by design (1e-15 m), not a result.
NOT_COMPARED = {"n_steps", "n_rhs", "n_events", "loop_residual"}


def _builds_an_fmu(crate):
    manifest = crate / "Cargo.toml"
    return manifest.is_file() and '"cdylib"' in manifest.read_text()


MODELS = sorted(p.name for p in (ROOT / "models").iterdir() if _builds_an_fmu(p))


def fmu_path(model, version):
    return TARGET / ("fmu3" if version == "3.0" else "fmu") / f"{model}.fmu"


class Result:
    """A run's time and named columns."""

    def __init__(self, time, columns):
        self.time = np.asarray(time, dtype=float)
        self.columns = {k: np.asarray(v, dtype=float) for k, v in columns.items()}

    @classmethod
    def from_structured(cls, array):
        names = array.dtype.names
        return cls(array["time"], {n: array[n] for n in names if n != "time"})

    @classmethod
    def from_csv(cls, path, prefix=""):
        with open(path) as f:
            rows = list(csv.reader(f))
        header = [h.strip().strip('"') for h in rows[0]]
        data = np.array([[float(x) if x.strip() not in ("", "true", "false") else float(x.strip() == "true") for x in r]
                         for r in rows[1:] if r], dtype=float)
        time_column = next(i for i, h in enumerate(header) if h.lower() == "time")
        columns = {h[len(prefix):]: data[:, i] for i, h in enumerate(header) if i != time_column and h.startswith(prefix)}
        return cls(data[:, time_column], columns)


# See the module's doc.
SAME_STEPS = 1e-9
FIXED_STEP_MASTER = 1e-6


def runner(*args, check=True):
    done = subprocess.run([str(RUNNER), *map(str, args)], capture_output=True, text=True)
    if check and done.returncode != 0:
        raise AssertionError(f"runner {' '.join(map(str, args))} failed:\n{done.stderr}")
    return done


_references = {}


def reference(model, tolerance, output_interval=None):
    """The runner's Co-Simulation run of the FMI 2.0 FMU at `tolerance` (cached)."""
    key = (model, tolerance, output_interval)
    if key not in _references:
        with tempfile.TemporaryDirectory() as tmp:
            out = pathlib.Path(tmp) / "ref.csv"
            args = ["simulate", fmu_path(model, "2.0"), "--tolerance", tolerance, "--out", out]
            if output_interval:
                args += ["--output-interval", output_interval]
            runner(*args)
            _references[key] = Result.from_csv(out)
    return _references[key]


def compare(result, ref, agreement, what, steps_past_end=False):
    """Checks that `result` reached `ref`'s end and agrees with it on the rows both have.
    Returns the worst deviation, as a fraction of the output's range.

    `steps_past_end`: the master knows no early end (Ecos goes on stepping after the FMU's
    fmi2Discard / fmi3 terminateSimulation); then the rows after the runner's end must hold
    the FMU's last values (the FMU refused to move on), and the comparison stops there."""
    interval = np.median(np.diff(ref.time)) if len(ref.time) > 1 else 1.0
    assert len(result.time) > 1, f"{what}: no rows"
    if steps_past_end and result.time[-1] > ref.time[-1] + interval:
        after = result.time > ref.time[-1] + interval * 1.0001
        for name, values in result.columns.items():
            tail = values[after]
            assert np.all(tail == tail[0]), f"{what}: {name} changed after the FMU's early end at t = {ref.time[-1]}"
        result = Result(result.time[~after], {k: v[~after] for k, v in result.columns.items()})
    end, ref_end = result.time[-1], ref.time[-1]
    # The end: the stop time, or the early end the runner reports (one output interval apart
    # at most: an importer records the last full communication point or the end itself).
    assert abs(end - ref_end) <= interval * 1.0001 + 1e-9, f"{what}: ended at t = {end}, the runner at t = {ref_end}"
    common = sorted(set(result.columns) & set(ref.columns) - NOT_COMPARED)
    assert common, f"{what}: no output in common with the runner ({sorted(result.columns)})"
    # Rows at the same times (to a millionth of the interval), excluding the last one when it
    # is an early end, where the derivatives of a limit position grow without bound.
    t_ref = np.round(ref.time / interval * 1e6).astype(np.int64)
    t_res = np.round(result.time / interval * 1e6).astype(np.int64)
    _, i_ref, i_res = np.intersect1d(t_ref, t_res, assume_unique=False, return_indices=True)
    keep = ref.time[i_ref] < min(end, ref_end) - 1e-12
    i_ref, i_res = i_ref[keep], i_res[keep]
    assert len(i_ref) >= min(5, len(ref.time) - 1), f"{what}: only {len(i_ref)} rows at the runner's times"
    worst = 0.0
    for name in common:
        a, b = result.columns[name][i_res], ref.columns[name][i_ref]
        span = max(np.max(np.abs(ref.columns[name])), 1e-12)
        deviation = np.max(np.abs(a - b)) / span
        assert np.all(np.isfinite(a)), f"{what}: {name} is not finite"
        assert deviation <= agreement, (f"{what}: {name} deviates from the runner by {deviation:.3g} of its range "
                                        f"(allowed {agreement:.3g}), worst at t = {ref.time[i_ref][np.argmax(np.abs(a - b))]}")
        worst = max(worst, deviation)
    return worst


# --- the importers ---------------------------------------------------------------------------

def fmpy_run(model, version, interface, tolerance):
    from fmpy import simulate_fmu

    kwargs = dict(fmi_type=interface, relative_tolerance=tolerance)
    if interface == "ModelExchange":
        # With its events recorded, the run's last row is the early end (a landing) itself.
        kwargs.update(solver="CVode", record_events=True)
    elif version == "3.0":
        # Early return lets fmpy record an early end at its time (FMI 2.0: Discard).
        kwargs["early_return_allowed"] = True
    return Result.from_structured(simulate_fmu(str(fmu_path(model, version)), **kwargs))


def libcosim_run(model, step, stop):
    """libcosim (FMI 2.0 Co-Simulation): one FMU, fixed steps, every Real output recorded."""
    from libcosimpy.CosimEnums import CosimVariableCausality, CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    log_output_level(CosimLogLevel.ERROR)
    execution = CosimExecution.from_step_size(step_size=int(round(step * 1e9)))
    index = execution.add_local_slave(CosimLocalSlave(fmu_path=str(fmu_path(model, "2.0")), instance_name=model))
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    refs = [(v.name.decode(), v.reference) for v in execution.slave_variables(index)
            if v.type == CosimVariableType.REAL.value and v.causality == CosimVariableCausality.OUTPUT.value]
    time, columns = [], {name: [] for name, _ in refs}

    def record(t):
        values = observer.last_real_values(slave_index=index, variable_references=[r for _, r in refs])
        time.append(t)
        for (name, _), v in zip(refs, values):
            columns[name].append(v)

    # libcosim initializes on its first step, so its rows start at t = h. Steps one at a time:
    # libcosim has no notion of an FMU's early end, so the run stops where a step fails, as
    # any master must.
    n = int(round(stop / step))
    for k in range(1, n + 1):
        if not execution.step():
            break
        record(k * step)
    return Result(time, columns)


def ecos_run(model, version, step, stop):
    """Ecos (FMI 2.0 and 3.0 Co-Simulation): one FMU, fixed steps, every Real output."""
    from ecospy import EcosSimulation, EcosSimulationStructure
    from fmpy import read_model_description

    outputs = [v.name for v in read_model_description(str(fmu_path(model, version))).modelVariables
               if v.causality == "output" and v.type in ("Real", "Float64")]
    structure = EcosSimulationStructure()
    structure.add_model("m", str(fmu_path(model, version)))
    time, columns = [], {name: [] for name in outputs}
    with EcosSimulation(structure=structure, step_size=step) as sim:
        sim.init()

        def record():
            time.append(sim.get_time())
            for name in outputs:
                columns[name].append(sim.get_real(f"m::{name}"))

        record()
        n = int(round(stop / step))
        for _ in range(n):
            before = sim.get_time()
            sim.step()
            if sim.get_time() <= before:
                break
            record()
        sim.terminate()
    return Result(time, columns)


def fmi_sim():
    """rust-fmi's fmi-sim on PATH (or in ~/.cargo/bin), or None."""
    found = shutil.which("fmi-sim")
    if found:
        return found
    cargo = pathlib.Path.home() / ".cargo" / "bin" / "fmi-sim"
    return str(cargo) if cargo.is_file() else None


def fmi_sim_run(model, version, interface, step, tmp):
    """fmi-sim: Co-Simulation with communication step `step`; Model Exchange with its explicit
    Euler at step / 10. A row per step (-n 0)."""
    out = pathlib.Path(tmp) / f"{model}-{version}-{interface}.csv"
    if interface == "CoSimulation":
        tail = ["co-simulation", "--step", repr(step)]
    else:
        tail = ["model-exchange", "--step", repr(step / 10)]
    command = [fmi_sim(), "--model", str(fmu_path(model, version)), "--output-file", str(out), *tail, "-n", "0"]
    done = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, f"fmi-sim refused {model} (FMI {version}, {interface}):\n{done.stderr[-2000:]}"
    return Result.from_csv(out)


def container_run(models, step, tmp):
    """An FMU container from fmu-manipulation-toolbox wrapping `models` (FMI 2.0 FMUs), run in
    fmpy's Co-Simulation: the container steps each FMU by `step` and exposes its outputs."""
    from fmpy import simulate_fmu

    tmp = pathlib.Path(tmp)
    for m in models:
        shutil.copy(fmu_path(m, "2.0"), tmp / f"{m}.fmu")
    description = tmp / "container.csv"
    description.write_text("rule;from_fmu;from_port;to_fmu;to_port\n" + "".join(f"FMU;{m}.fmu;;;\n" for m in models))
    tool = pathlib.Path(sys.executable).parent / "fmucontainer"
    command = [str(tool) if tool.is_file() else "fmucontainer", "-container", f"{description}:{step}", "-fmu-directory", str(tmp)]
    done = subprocess.run(command, capture_output=True, text=True, timeout=600, cwd=tmp)
    container = tmp / "container.fmu"
    assert done.returncode == 0 and container.is_file(), f"fmucontainer failed:\n{done.stdout[-2000:]}{done.stderr[-2000:]}"
    return simulate_fmu(str(container), fmi_type="CoSimulation", output_interval=step), done.stdout + done.stderr
