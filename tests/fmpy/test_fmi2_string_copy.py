"""fmi2SetString must copy the text it is given: the caller's strings are only lent for the call.
What `runner validate` concludes (its check variables.string: the text set, the caller's buffer
overwritten, the value read back must be unchanged) against fmpy driving the same binary
(fmpy.fmi2.FMU2Slave: its own fmi2SetString with a buffer this test owns and then overwrites,
its own getString).

fmpy's high-level setString cannot show the fault: the bytes it passes are freed after the
call, so an FMU that kept the pointer reads freed memory, which may still hold the text. Hence
the buffer of our own here. Checked on the C test FMU (tests/c_fmu/faults.c) correct and with
FAULT_STRING_COPY (fmi2SetString keeps the caller's pointer, fmi2GetString hands it back), and
on the Reference FMU Feedthrough, whose String_input both importers must find copied."""

import ctypes
import json
import subprocess
import zipfile

import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave, fmi2OK, fmi2String, fmi2ValueReference

from conftest import ROOT, TARGET

RUNNER = TARGET / "release" / "runner"
C_FMU = ROOT / "tests" / "c_fmu"
FEEDTHROUGH = ROOT.parent / "shared" / "reference-fmus" / "fmi2" / "Feedthrough.fmu"


def c_fmu(tmp_path, flags):
    """The FMI 2.0 C test FMU built with `flags`, as an FMU archive."""
    so = tmp_path / "faults.so"
    subprocess.run(["cc", "-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-o", str(so), str(C_FMU / "faults.c"), *flags,
                    "-lm"], check=True)
    path = tmp_path / "faults.fmu"
    with zipfile.ZipFile(path, "w") as z:
        z.write(C_FMU / "faults.xml", "modelDescription.xml")
        z.write(so, "binaries/linux64/faults.so")
    return path


def fmpy_reads_back(path, name, after_initialization):
    """fmpy: sets String `name` from a buffer of ours (after initialization to a text of its
    own, else in Initialization Mode to its start value), overwrites the buffer with '#', and
    reads the variable back after initialization; what it read and what was set."""
    md = read_model_description(str(path))
    variable = {v.name: v for v in md.modelVariables}[name]
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(path)), modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName="fmpy")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    if after_initialization:
        fmu.exitInitializationMode()
    text = b"fmpy's own text" if after_initialization else variable.start.encode()
    buffer = ctypes.create_string_buffer(text)
    vrs = (fmi2ValueReference * 1)(variable.valueReference)
    values = (fmi2String * 1)(ctypes.cast(buffer, fmi2String))
    assert fmu.fmi2SetString(fmu.component, vrs, 1, values) == fmi2OK
    ctypes.memset(buffer, ord("#"), len(text))
    if not after_initialization:
        fmu.exitInitializationMode()
    # fmpy 0.3 hands back the bytes fmi2GetString pointed to.
    got = fmu.getString([variable.valueReference])[0].decode()
    fmu.terminate()
    fmu.freeInstance()
    return got, text.decode()


def runner_verdicts(path, tmp_path):
    """`runner validate`'s severity of variables.string for each interface."""
    report = tmp_path / "report.json"
    done = subprocess.run([str(RUNNER), "validate", str(path), "--report", str(report)], capture_output=True, text=True)
    assert done.returncode in (0, 1), done.stderr
    findings = [f for r in json.loads(report.read_text())["reports"] for f in r["findings"]]
    return {f["interface"]: f["severity"] for f in findings if f["check"] == "variables.string"}


@pytest.mark.parametrize("flags, copies", [([], True), (["-DFAULT_STRING_COPY"], False)])
def test_runner_and_fmpy_agree_on_the_c_fmu_with_and_without_the_copy(flags, copies, tmp_path):
    path = c_fmu(tmp_path, flags)
    # label is a fixed parameter: set in Initialization Mode, as the validator does.
    got, wanted = fmpy_reads_back(path, "label", after_initialization=False)
    assert (got == wanted) == copies, (got, wanted)
    if not copies:
        assert got == "#" * len(wanted), "fmpy reads the caller's overwritten buffer"
    verdict = "passed" if copies else "error"
    assert runner_verdicts(path, tmp_path) == {"Co-Simulation": verdict, "Model Exchange": verdict}


def test_runner_and_fmpy_agree_that_feedthrough_copies_its_string_input(tmp_path):
    got, wanted = fmpy_reads_back(FEEDTHROUGH, "String_input", after_initialization=True)
    assert got == wanted
    assert runner_verdicts(FEEDTHROUGH, tmp_path) == {"Co-Simulation": "passed", "Model Exchange": "passed"}
