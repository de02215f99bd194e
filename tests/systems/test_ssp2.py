"""The SSP 2.0 system systems/quarter_car_road_ssp2 against its SSP 1.0 twin
systems/quarter_car_road. libcosim (libcosimpy 0.0.6) ignores the SSD's version but refuses SSP
2.0's connector types (Float64, Int32) and FMI 3.0 FMUs, so the twin is the independent check: the same road and car, written once in SSP 1.0 (Real connectors and
parameters, both FMUs FMI 2.0) and once in SSP 2.0 (the road as its FMI 3.0 FMU behind Float64
and Int32 connectors, SSP 2.0's Int32 and Float64 parameter values).

The two road FMUs are one Rust model exported twice, the car is the same FMI 2.0 FMU and the
master is the same, so every FMU receives the same values at the same times and computes the
same operations: the results must be equal to the bit, under both masters and both couplings
(the FMI 3.0 road passes the same exact output derivatives through fmi3GetOutputDerivatives as
the FMI 2.0 one through fmi2GetRealOutputDerivatives)."""

import shutil
import zipfile

import numpy as np
import pytest

from systems_tools import ROOT, TARGET, runner, runner_csv, ssp_path


def run(tmp_path, target, *args):
    folder = tmp_path / f"run{len(list(tmp_path.iterdir()))}"
    folder.mkdir()
    return runner_csv(folder, target, *args)


@pytest.mark.parametrize("master", ["jacobi", "gauss-seidel"])
@pytest.mark.parametrize("coupling", [[], ["--coupling", "hold"]], ids=["default", "hold"])
def test_the_ssp2_system_equals_its_ssp1_twin_to_the_bit(tmp_path, master, coupling):
    args = ["--master", master, *coupling]
    header1, rows1 = run(tmp_path, ssp_path("quarter_car_road"), *args)
    header2, rows2 = run(tmp_path, ssp_path("quarter_car_road_ssp2"), *args)
    assert header1 == header2
    assert rows1.shape == rows2.shape and rows1.shape[0] == 10001
    differ = np.flatnonzero((rows1 != rows2).any(axis=1))
    assert differ.size == 0, f"rows differ from t = {rows1[differ[0], 0]}: {header1}"


def fmi3_twin(tmp_path, car_connector="Float64"):
    """systems/quarter_car_road_ssp2 as a folder with both components as FMI 3.0 FMUs (the car
    behind `car_connector` connectors)."""
    folder = tmp_path / "fmi3_twin"
    (folder / "resources" / "fmu3").mkdir(parents=True)
    for f in (ROOT / "systems" / "quarter_car_road_ssp2").iterdir():
        shutil.copy(f, folder)
    for model in ("road", "quarter_car"):
        shutil.copy(TARGET / "fmu3" / f"{model}.fmu", folder / "resources" / "fmu3" / f"{model}.fmu")
    ssd = folder / "SystemStructure.ssd"
    text = ssd.read_text()
    text = text.replace('source="resources/quarter_car.fmu"', 'source="resources/fmu3/quarter_car.fmu"')
    text = text.replace('<ssc:Real unit="m/s"/>', f'<ssc:{car_connector} unit="m/s"/>')
    ssd.write_text(text)
    return folder


@pytest.mark.parametrize("master", ["jacobi", "gauss-seidel"])
def test_an_all_fmi3_system_equals_the_ssp1_twin_under_the_hold(tmp_path, master):
    """Both components FMI 3.0: FMI 3.0 has no input derivatives, so the car holds its input and
    only the hold is the same coupling as the SSP 1.0 twin's; under it, the same bits."""
    args = ["--master", master, "--coupling", "hold"]
    header1, rows1 = run(tmp_path, ssp_path("quarter_car_road"), *args)
    header3, rows3 = run(tmp_path, fmi3_twin(tmp_path), *args)
    assert header1 == header3
    assert np.array_equal(rows1, rows3)


def test_a_connector_type_that_is_not_its_variables_is_refused(tmp_path):
    folder = fmi3_twin(tmp_path, car_connector="Float32")
    done = runner("simulate", folder, "--out", tmp_path / "x.csv")
    assert done.returncode != 0
    assert ("component 'car': connector 'z_r_dot_ext' (line 25) is declared Float32, "
            "but the FMU's variable 'z_r_dot_ext' is Float64") in done.stderr, done.stderr


def test_the_build_packs_the_fmi3_fmu_where_the_ssd_names_it():
    """`resources/fmu3/<model>.fmu` in an SSD is the FMI 3.0 FMU (target/fmu3), and
    `resources/<model>.fmu` the FMI 2.0 one (target/fmu)."""
    with zipfile.ZipFile(ssp_path("quarter_car_road_ssp2")) as z:
        names = set(z.namelist())
        assert {"SystemStructure.ssd", "road.ssv", "car.ssv", "resources/fmu3/road.fmu",
                "resources/quarter_car.fmu"} <= names, names
        for entry, version in (("resources/fmu3/road.fmu", "3.0"), ("resources/quarter_car.fmu", "2.0")):
            with zipfile.ZipFile(z.open(entry)) as fmu:
                assert f'fmiVersion="{version}"' in fmu.read("modelDescription.xml").decode(), entry


@pytest.mark.parametrize("element, message", [
    ('<ssc:Dimension size="2"/>', "connector 'z_r_dot' of component 'road' is an array connector (ssc:Dimension, sizes 2): "
                                  "array connectors are not supported, only scalars"),
    ('<ssd:Clock name="tick"/>', "connector 'z_r_dot' of component 'road' is clocked by clock 'tick' (ssd:Clock): "
                                 "clocked connectors are not supported"),
], ids=["array", "clocked"])
def test_array_and_clocked_connectors_are_refused_by_name(tmp_path, element, message):
    """What the master cannot pass is refused before anything is loaded, with the SSD's line."""
    folder = fmi3_twin(tmp_path)
    ssd = folder / "SystemStructure.ssd"
    ssd.write_text(ssd.read_text().replace('<ssc:Float64 unit="m/s"/></ssd:Connector>',
                                           f'<ssc:Float64 unit="m/s"/>{element}</ssd:Connector>', 1))
    done = runner("simulate", folder, "--out", tmp_path / "x.csv")
    assert done.returncode != 0
    assert f"SystemStructure.ssd, line 15: {message}" in done.stderr, done.stderr
