"""Our FMI 3.0 FMUs ship an FMI-LS-REF reference result of their default experiment
(extra/org.fmi-standard.fmi-ls-ref/, written by `runner build`). fmpy, an independent importer,
reads the shipped CSV with its own `read_csv` (the FMI cross-check convention) and pandas reads
it too, to the same numbers; and fmpy's own Co-Simulation run of the FMU's DefaultExperiment
stays inside the runner's default tube around it (|y - ref| <= 1e-3 (|ref| + max|ref|)), which is
what another importer checking itself against our models would do."""

import tomllib
import xml.etree.ElementTree as ET
import zipfile

import numpy as np
import pandas as pd
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.util import read_csv

from conftest import MODELS, ROOT, fmu_path

LS_REF = "extra/org.fmi-standard.fmi-ls-ref/"


def shipped(fmu, tmp_path):
    """The manifest's result file, extracted: its path."""
    with zipfile.ZipFile(fmu) as z:
        manifest = ET.fromstring(z.read(LS_REF + "fmi-ls-manifest.xml"))
        related = [r for r in manifest.iter("Related") if r.get("role") == "result"]
        assert len(related) == 1 and related[0].get("type") == "text/csv"
        path = tmp_path / related[0].get("source")
        path.write_bytes(z.read(LS_REF + related[0].get("source")))
    return path


@pytest.mark.parametrize("model", MODELS)
def test_fmpy_reads_the_shipped_reference_and_reproduces_it(model, tmp_path):
    fmu = fmu_path(model, "3.0")
    path = shipped(fmu, tmp_path)
    ref = read_csv(path)
    md = read_model_description(fmu)
    # Every output but the solver's counters (they count the reference run's own work) and
    # those experiment.toml's [reference] omits (rounding noise).
    toml = ROOT / "models" / model / "experiment.toml"
    experiment = tomllib.loads(toml.read_text()) if toml.is_file() else {}
    left_out = {"n_steps", "n_rhs", *experiment.get("reference", {}).get("omit", [])}
    outputs = [v.name for v in md.modelVariables if v.causality == "output" and v.name not in left_out]
    assert list(ref.dtype.names) == ["time"] + outputs
    frame = pd.read_csv(path)
    for name in ref.dtype.names:
        assert np.array_equal(ref[name], frame[name].to_numpy(dtype=float)), name
    default = md.defaultExperiment
    assert ref["time"][0] == float(default.startTime or 0) and ref["time"][-1] <= float(default.stopTime)
    # On the DefaultExperiment's grid, as the reference (fmpy's own default is coarser). The
    # reference rows are compared where fmpy has a row at the same time: a run the model ends
    # early (the trebuchet's, at impact) has its last reference row at the end time, between two
    # of fmpy's points, across a jump of its discrete outputs that interpolation cannot follow.
    run = simulate_fmu(fmu, fmi_type="CoSimulation", output=outputs, output_interval=float(default.stepSize))
    at = np.clip(np.searchsorted(run["time"], ref["time"] - 1e-9), 0, len(run) - 1)
    same = np.abs(run["time"][at] - ref["time"]) <= 1e-9
    assert np.count_nonzero(~same) <= 1, f"{model}: {np.count_nonzero(~same)} reference times fmpy has no row at"
    for name in outputs:
        expected, ours = ref[name][same], run[name][at[same]].astype(float)
        bound = 1e-3 * (np.abs(expected) + np.max(np.abs(ref[name])))
        worst = np.argmax(np.abs(ours - expected) - bound)
        assert abs(ours[worst] - expected[worst]) <= bound[worst], \
            f"{model}: {name} at t = {ref['time'][same][worst]}: fmpy {ours[worst]}, reference {expected[worst]}"
