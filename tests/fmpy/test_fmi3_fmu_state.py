"""FMU state of FMI 3.0 FMUs: what `runner validate` concludes about a restore (its checks
capability.fmu-state and capability.serialize: the continuation after fmi3SetFMUState, of the
state itself or of its serialized bytes, equals the first continuation bit for bit) against
fmpy's own round trip on the same binary (fmpy.fmi3.FMU3Slave getFMUState / setFMUState /
serializeFMUState / deserializeFMUState, on a grid of its own, without Event Mode).

The two importers share no code and drive the FMU with different call sequences, so agreeing
verdicts say the probe judges the FMU, not its own bookkeeping. The comparison is exact: a
restored FMU recomputes the same floating-point operations, so any difference is a fault.
Checked on Reference FMUs that declare canGetAndSetFMUState and canSerializeFMUState, and on the
C test FMU (tests/c_fmu/fmi3_faults.c) correct and with FAULT_STATE (a restore that brings back
the start values), which both importers must see fail."""

import json
import subprocess
import zipfile

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi3 import FMU3Slave

from conftest import FMU3_DIR, ROOT, TARGET

REFERENCE = ROOT.parent / "shared" / "reference-fmus" / "fmi3"
RUNNER = TARGET / "release" / "runner"
C_FMU = ROOT / "tests" / "c_fmu"
# Communication steps of fmpy's run; the state is saved after half of them.
STEPS = 100


def fmpy_restore_reproduces(path, serialized):
    """fmpy: run to half-way, save the state (serialized and deserialized when asked), run on,
    restore, run on again; whether both continuations give the same outputs to the bit."""
    md = read_model_description(str(path))
    outputs = [v.valueReference for v in md.modelVariables
               if v.causality == "output" and v.type == "Float64" and not v.dimensions]
    assert outputs, f"{path.name} has no scalar Float64 outputs to compare"
    fmu = FMU3Slave(guid=md.guid, unzipDirectory=extract(str(path)), modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName="fmpy")
    fmu.instantiate()
    experiment = md.defaultExperiment
    start = float(experiment.startTime or 0.0) if experiment else 0.0
    stop = float(experiment.stopTime or start + 1.0) if experiment else start + 1.0
    h = (stop - start) / STEPS
    fmu.enterInitializationMode(startTime=start, stopTime=stop)
    fmu.exitInitializationMode()

    def run(k0):
        rows = []
        for k in range(k0, STEPS):
            fmu.doStep(currentCommunicationPoint=start + k * h, communicationStepSize=h)
            rows.append(fmu.getFloat64(outputs))
        return np.array(rows)

    for k in range(STEPS // 2):
        fmu.doStep(currentCommunicationPoint=start + k * h, communicationStepSize=h)
    state = fmu.getFMUState()
    if serialized:
        data = fmu.serializeFMUState(state)
        fmu.freeFMUState(state)
    first = run(STEPS // 2)
    if serialized:
        state = fmu.deserializeFMUState(data)
    fmu.setFMUState(state)
    second = run(STEPS // 2)
    fmu.freeFMUState(state)
    fmu.terminate()
    fmu.freeInstance()
    return first.tobytes() == second.tobytes()


def runner_verdicts(path, tmp_path):
    """`runner validate`'s severity of capability.fmu-state and capability.serialize for
    Co-Simulation, the interface fmpy's round trip used."""
    report = tmp_path / "report.json"
    done = subprocess.run([str(RUNNER), "validate", str(path), "--report", str(report)], capture_output=True, text=True)
    assert done.returncode in (0, 1), done.stderr
    findings = [f for r in json.loads(report.read_text())["reports"] for f in r["findings"]]
    verdicts = {}
    for check in ("capability.fmu-state", "capability.serialize"):
        severities = {f["severity"] for f in findings if f["check"] == check and f.get("interface") == "Co-Simulation"}
        verdicts[check] = "error" if "error" in severities else "passed" if "passed" in severities else str(severities)
    return verdicts


def c_fmu(tmp_path, flags):
    """The C test FMU built with `flags`, as an FMU archive."""
    so = tmp_path / "fmi3_faults.so"
    subprocess.run(["cc", "-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-o", str(so), str(C_FMU / "fmi3_faults.c"),
                    *flags, "-lm"], check=True)
    path = tmp_path / "fmi3_faults.fmu"
    with zipfile.ZipFile(path, "w") as z:
        z.write(C_FMU / "fmi3_faults.xml", "modelDescription.xml")
        z.write(so, "binaries/x86_64-linux/fmi3_faults.so")
    return path


@pytest.mark.parametrize("model", ["BouncingBall", "Dahlquist", "VanDerPol"])
def test_runner_and_fmpy_agree_that_reference_fmus_restore_their_state(model, tmp_path):
    path = REFERENCE / f"{model}.fmu"
    cs = read_model_description(str(path)).coSimulation
    # fmpy names the FMI 3.0 attributes as FMI 2.0 spells them.
    assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate, f"{model} is expected to declare FMU state"
    assert fmpy_restore_reproduces(path, serialized=False) and fmpy_restore_reproduces(path, serialized=True)
    assert runner_verdicts(path, tmp_path) == {"capability.fmu-state": "passed", "capability.serialize": "passed"}


@pytest.mark.parametrize("flags, restores", [([], True), (["-DFAULT_STATE"], False)])
def test_runner_and_fmpy_agree_on_the_c_fmu_with_and_without_a_broken_restore(flags, restores, tmp_path):
    path = c_fmu(tmp_path, flags)
    assert fmpy_restore_reproduces(path, serialized=False) == restores
    assert fmpy_restore_reproduces(path, serialized=True) == restores
    verdict = "passed" if restores else "error"
    assert runner_verdicts(path, tmp_path) == {"capability.fmu-state": verdict, "capability.serialize": verdict}


# The checks of the FMI 3.0 capability probes, and the skips allowed for each (reasons that
# leave nothing to check: the run ends before its half-way point, there are no Strings).
CAPABILITY_CHECKS = {
    "capability.fmu-state": "not exercised: the model ended the run before its half-way point",
    "capability.serialize": "not exercised: the model ended the run before its half-way point",
    "capability.threads": None,
    "arguments.null-instance": None,
    "arguments.null-arrays": None,
    "variables.string": "the FMU has no scalar String variables",
}


def test_our_fmi3_fmus_pass_every_capability_probe(tmp_path):
    """Every FMI 3.0 FMU `runner build` makes declares FMU state and serialization and may be
    instantiated many times: each capability probe must pass on both interfaces (tests/run only
    sees that validate is clean, which a probe skipped for a wrong reason would also be). Of the
    skips only the two that leave nothing to check are allowed, and some FMU must have Strings."""
    fmus = sorted(FMU3_DIR.glob("*.fmu"))
    assert fmus, f"no FMI 3.0 FMUs in {FMU3_DIR}: run `cargo run --release -p runner -- build` first"
    report = tmp_path / "report.json"
    done = subprocess.run([str(RUNNER), "validate", *map(str, fmus), "--report", str(report)], capture_output=True, text=True)
    assert done.returncode == 0, done.stdout
    with_strings = 0
    for r in json.loads(report.read_text())["reports"]:
        for interface in ("Co-Simulation", "Model Exchange"):
            for check, allowed_skip in CAPABILITY_CHECKS.items():
                found = [f for f in r["findings"] if f["check"] == check and f.get("interface") == interface]
                verdicts = {(f["severity"], f["message"] if f["severity"] == "skipped" else "") for f in found}
                assert verdicts in ({("passed", "")}, {("skipped", allowed_skip)}), f"{r.get('model_name')} {interface} {check}: {found}"
                with_strings += check == "variables.string" and verdicts == {("passed", "")}
    assert with_strings > 0, "no FMU of ours has String variables any more: the String probe is then untested on them"
