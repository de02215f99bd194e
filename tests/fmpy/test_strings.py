"""String variables: road's String parameter `table` (the measured profile's file) through two
independent importers, fmpy (FMI 2.0 and 3.0, `start_values={'table': ...}`) and the runner
(`--set table=...`), both against the profile computed here from the file itself (linear
interpolation of its rows); the fixed-parameter rule and the errors for bad files as an importer
meets them; and the Reference FMU Feedthrough's String variables through the runner and fmpy."""

import csv
import pathlib
import subprocess

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

from conftest import ROOT, TARGET, fmu_path

RUNNER = TARGET / "release" / "runner"
RESOURCES = ROOT / "models" / "road" / "resources"
REFERENCE = ROOT.parent / "shared" / "reference-fmus"


@pytest.fixture(params=["2.0", "3.0"])
def version(request):
    return request.param


def profile_rows(path):
    """The (x, z) rows of a profile file, read here independently of the FMU."""
    rows = [line.strip() for line in pathlib.Path(path).read_text().splitlines()]
    rows = [r for r in rows if r and not r.startswith("#")]
    assert rows[0] == "x,z"
    xz = np.array([[float(c) for c in r.split(",")] for r in rows[1:]])
    return xz[:, 0], xz[:, 1]


def runner(*args):
    return subprocess.run([str(RUNNER), *map(str, args)], capture_output=True, text=True, timeout=600)


def runner_csv(out, *args):
    done = runner("simulate", *args, "--out", out)
    assert done.returncode == 0, done.stderr
    with open(out) as f:
        rows = list(csv.reader(f))
    return rows[0], np.array([[float(x) for x in r] for r in rows[1:]])


def fmpy_road(version, start):
    return simulate_fmu(str(fmu_path("road", version)), fmi_type="CoSimulation", start_values=start, stop_time=10.0,
                        output_interval=1e-3)


def check_profile(time, z_r, z_r_dot, table, speed):
    """z_r = z(x) with x = speed t, z linear between the file's rows, held beyond them, and
    z_r' = speed z'(x). x = v t is integrated by the FMU's DOPRI5 exactly but for rounding, a
    few ulps of x per step: over 10^4 steps below 1e-11 m, which moves z by slope * 1e-11
    (slopes here are below 1): hence 1e-11. The slope is compared away from the rows (2 mm),
    where the rounding of x could pick the neighbouring interval."""
    xs, zs = profile_rows(table)
    x = speed * time
    assert np.max(np.abs(z_r - np.interp(x, xs, zs))) < 1e-11
    slopes = np.diff(zs) / np.diff(xs)
    inside = (x > xs[0]) & (x < xs[-1]) & (np.min(np.abs(x[:, None] - xs[None, :]), axis=1) > 2e-3)
    k = np.searchsorted(xs, x[inside], side="right") - 1
    assert np.max(np.abs(z_r_dot[inside] - speed * slopes[k])) < 1e-12
    # Something of the file shows: the profile is not flat.
    assert np.ptp(z_r) > 0.01


def test_fmpy_reads_table_as_a_fixed_string_parameter(version):
    """The description as fmpy reads it: `table` is a String parameter, fixed, start
    profile.csv (MODELS.md), and fmpy's validation of the FMU finds nothing."""
    path = str(fmu_path("road", version))
    md = read_model_description(path)
    table = {v.name: v for v in md.modelVariables}["table"]
    assert (table.type, table.causality, table.variability, table.start) == ("String", "parameter", "fixed", "profile.csv")
    assert validate_fmu(path) == []


def test_fmpy_and_the_runner_run_the_table_the_parameter_names(version, tmp_path):
    """The second shipped sample by its name (resolved in the FMU's resources/): fmpy and the
    runner drive the same binary through the same calls, so their z_r and z_r' agree bit for
    bit; both are the file's linear interpolation."""
    start = {"profile": 2, "speed": 1.0, "table": "speed_bump.csv"}
    result = fmpy_road(version, start)
    header, rows = runner_csv(tmp_path / "road.csv", fmu_path("road", version), "--stop-time", 10, "--output-interval",
                              1e-3, *[a for k, v in start.items() for a in ("--set", f"{k}={v}")])
    assert header[:4] == ["time", "x", "z_r", "z_r_dot"]
    assert np.array_equal(rows[:, 0], result["time"])
    for j, name in enumerate(header[1:4], 1):
        assert np.array_equal(rows[:, j], result[name]), name
    check_profile(result["time"], result["z_r"], result["z_r_dot"], RESOURCES / "speed_bump.csv", 1.0)


def test_an_absolute_path_reads_a_file_outside_the_fmu(version, tmp_path):
    """A file of the user's own, by absolute path (and by file URI for the runner): both
    importers read it, and the road is its interpolation at 2 m/s."""
    mine = tmp_path / "mine.csv"
    mine.write_text("# a washboard of 5 cm ridges\nx,z\n0,0\n2,0.05\n4,0\n6,0.05\n8,0\n30,0\n")
    result = fmpy_road(version, {"profile": 2, "speed": 2.0, "table": str(mine)})
    check_profile(result["time"], result["z_r"], result["z_r_dot"], mine, 2.0)
    _, rows = runner_csv(tmp_path / "uri.csv", fmu_path("road", version), "--set", "profile=2", "--set", "speed=2",
                         "--set", f"table={mine.as_uri()}", "--stop-time", 10, "--output-interval", 1e-3)
    assert np.array_equal(rows[:, 2], result["z_r"])


def test_the_default_table_gives_the_results_it_gave_before_the_parameter(version, tmp_path):
    """Naming the default file explicitly is the same run as not setting `table`."""
    _, default = runner_csv(tmp_path / "a.csv", fmu_path("road", version), "--set", "profile=2")
    _, named = runner_csv(tmp_path / "b.csv", fmu_path("road", version), "--set", "profile=2", "--set", "table=profile.csv")
    assert np.array_equal(default, named)
    check_profile(default[:, 0], default[:, 2], default[:, 3], RESOURCES / "profile.csv", 30.0)


def test_missing_and_bad_tables_are_named_with_the_line(version, tmp_path):
    done = runner("simulate", fmu_path("road", version), "--set", "profile=2", "--set", "table=nowhere.csv", "--out",
                  tmp_path / "x.csv")
    assert done.returncode == 1 and "cannot read the profile table nowhere.csv" in done.stderr, done.stderr
    bad = tmp_path / "bad.csv"
    bad.write_text("x,z\n0,0\n1,0.1\n1,0.2\n")
    done = runner("simulate", fmu_path("road", version), "--set", "profile=2", "--set", f"table={bad}", "--out",
                  tmp_path / "y.csv")
    assert done.returncode == 1 and f"{bad}, line 4: x must increase" in done.stderr, done.stderr


def test_the_table_is_fixed_after_initialization(version, tmp_path):
    """fmpy's own calls: GetString gives what SetString set (in Initialization Mode), and
    setting the fixed parameter after initialization is refused with an error status."""
    path = str(fmu_path("road", version))
    md = read_model_description(path)
    vr = {v.name: v.valueReference for v in md.modelVariables}["table"]
    directory = extract(path, unzipdir=tmp_path / "unzipped")
    slave_class = FMU2Slave if version == "2.0" else FMU3Slave
    fmu = slave_class(guid=md.guid, unzipDirectory=directory, modelIdentifier=md.coSimulation.modelIdentifier,
                      instanceName="road")
    fmu.instantiate()
    if version == "2.0":
        fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.setString([vr], ["speed_bump.csv"])
    got = fmu.getString([vr])[0]
    assert (got.decode() if isinstance(got, bytes) else got) == "speed_bump.csv"
    fmu.exitInitializationMode()
    with pytest.raises(Exception, match=r"SetString failed with status 3 \(error\)"):
        fmu.setString([vr], ["profile.csv"])
    fmu.terminate()
    fmu.freeInstance()


def test_the_sweep_refuses_a_string_param_clearly(tmp_path):
    done = runner("sweep", fmu_path("road"), "--param", "table=a.csv,b.csv", "--metric", "m=max(z_r)", "--out",
                  tmp_path / "s.csv")
    assert done.returncode != 0
    assert "'a.csv' is not a number" in done.stderr and "--set NAME=TEXT" in done.stderr, done.stderr


def test_runner_info_lists_the_string_parameter(version):
    done = runner("info", fmu_path("road", version))
    assert done.returncode == 0, done.stderr
    line = next(line for line in done.stdout.splitlines() if line.startswith("table "))
    assert "String" in line and "fixed" in line and '"profile.csv"' in line, line


@pytest.mark.parametrize("reference", ["fmi2", "fmi3"])
def test_feedthrough_strings_through_fmpy_and_the_runner(reference, tmp_path):
    """The Reference FMU Feedthrough (third-party) copies String_input to String_output: fmpy
    sets the input and reads the output with its own calls; the runner's importer does the same
    (runner/importer/tests/strings.rs), and its CSV has the String output column, in both
    versions."""
    path = REFERENCE / reference / "Feedthrough.fmu"
    if not path.is_file():
        pytest.skip(f"{path} is not here")
    md = read_model_description(str(path))
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    directory = extract(str(path), unzipdir=tmp_path / "unzipped")
    slave_class = FMU2Slave if reference == "fmi2" else FMU3Slave
    fmu = slave_class(guid=md.guid, unzipDirectory=directory, modelIdentifier=md.coSimulation.modelIdentifier,
                      instanceName="feedthrough")
    fmu.instantiate()
    if reference == "fmi2":
        fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.setString([vrs["String_input"]], ["héllo, wörld"])
    fmu.exitInitializationMode()
    fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=0.1)
    got = fmu.getString([vrs["String_output"]])[0]
    fmpy_text = got.decode() if isinstance(got, bytes) else got
    fmu.terminate()
    fmu.freeInstance()
    assert fmpy_text == "héllo, wörld"
    done = runner("simulate", path, "--set", "String_input=héllo, wörld", "--stop-time", 0.2, "--output-interval", 0.1,
                  "--out", tmp_path / "f.csv")
    assert done.returncode == 0, done.stderr
    with open(tmp_path / "f.csv") as f:
        rows = list(csv.reader(f))
    assert dict(zip(rows[0], rows[-1]))["String_output"] == fmpy_text


SSD = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0" name="bump">
  <ssd:System name="bump">
    <ssd:Elements>
      <ssd:Component name="road" source="road.fmu" implementation="CoSimulation">
        <ssd:Connectors>
          <ssd:Connector name="z_r" kind="output"><ssc:Real unit="m"/></ssd:Connector>
          <ssd:Connector name="table" kind="parameter"><ssc:String/></ssd:Connector>
        </ssd:Connectors>
        <ssd:ParameterBindings>
          <ssd:ParameterBinding>
            <ssd:ParameterValues>
              <ssv:ParameterSet version="1.0" name="road">
                <ssv:Parameters>
                  <ssv:Parameter name="profile"><ssv:Integer value="2"/></ssv:Parameter>
                  <ssv:Parameter name="speed"><ssv:Real value="1"/></ssv:Parameter>
                  <ssv:Parameter name="table"><ssv:String value="speed_bump.csv"/></ssv:Parameter>
                </ssv:Parameters>
              </ssv:ParameterSet>
            </ssd:ParameterValues>
          </ssd:ParameterBinding>
        </ssd:ParameterBindings>
      </ssd:Component>
    </ssd:Elements>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="10"/>
</ssd:SystemStructureDescription>
"""


def test_an_ssp_string_binding_sets_the_table(tmp_path):
    """A system whose ParameterBinding gives road's table as an ssv:String: the runner's system
    run is the single FMU's run with --set table=, at the same communication points."""
    system = tmp_path / "bump"
    system.mkdir()
    (system / "road.fmu").write_bytes(fmu_path("road", "2.0").read_bytes())
    (system / "SystemStructure.ssd").write_text(SSD)
    header, rows = runner_csv(tmp_path / "system.csv", system, "--output-interval", 0.01)
    _, single = runner_csv(tmp_path / "single.csv", fmu_path("road", "2.0"), "--set", "profile=2", "--set", "speed=1",
                           "--set", "table=speed_bump.csv", "--output-interval", 0.01, "--stop-time", 10)
    j = header.index("road.z_r")
    assert np.array_equal(rows[:, 0], single[:, 0])
    assert np.array_equal(rows[:, j], single[:, 2])
    check_profile(rows[:, 0], rows[:, j], single[:, 3], RESOURCES / "speed_bump.csv", 1.0)
