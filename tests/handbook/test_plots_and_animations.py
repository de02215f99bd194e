"""`runner simulate --plot` and `runner animate` on the lab's FMUs, as the README documents them:
display units on the command line (checked against the handbook's own units: 1 in = 0.0254 m,
1 lbf = 4.4482216152605 N, 1 rpm = 2 pi / 60 rad/s), events marked where the FMU's discrete
outputs change, overlays, PNG plots (opened as images: their size, ink and anti-aliased curves) in
every command that takes --plot, and GIFs of FMUs given by path with an experiment file."""

import math
import re
import shutil

import numpy as np

import xml.etree.ElementTree as ET

from handbook_tools import ROOT, blend_levels, check_png_figure, fmu, png_size, read_gif, runner


def csv(path):
    return np.genfromtxt(path, delimiter=",", names=True)


def svg_texts(path):
    return [t.strip() for t in re.findall(r"<text[^>]*>([^<]*)</text>", path.read_text())]


def test_set_converts_declared_display_units_and_refuses_others(tmp_path):
    runner("simulate", "pendulum", "--set", "theta0=120deg", "--set", "omega0=10rpm", "--stop-time", "0.01",
           "--out", tmp_path / "p.csv")
    p = csv(tmp_path / "p.csv")
    assert abs(p["theta"][0] - 2 * math.pi / 3) < 1e-15 and abs(p["omega"][0] - math.pi / 3) < 1e-15
    # Ex. 4's prelab in its own units: k = 10 lbf/in, m = 2 lbf s^2/in, x0 = 1 in, at rest:
    # a(0) = -k x0 / m = -5 in/s^2.
    runner("simulate", "mass_spring_damper", "--set", "k=10lbf/in", "--set", "m=2lbf.s2/in", "--set", "x0=1in",
           "--stop-time", "0.01", "--out", tmp_path / "m.csv")
    m = csv(tmp_path / "m.csv")
    assert abs(m["a"][0] - (-5 * 0.0254)) < 1e-12
    refused = runner("simulate", "pendulum", "--set", "theta0=15rpm", "--out", tmp_path / "x.csv", check=False)
    assert refused.returncode == 1
    assert "'theta0' cannot be given in 'rpm'" in refused.stderr and "rad, deg" in refused.stderr, refused.stderr
    assert not (tmp_path / "x.csv").exists()


def test_the_default_plot_shows_the_continuous_outputs_in_display_units_with_the_release_marked(tmp_path):
    runner("simulate", "bumper", "--plot", tmp_path / "b.svg", "--out", tmp_path / "b.csv")
    texts = svg_texts(tmp_path / "b.svg")
    for label in ["x (m)", "v (m/s)", "a (m/s2)", "x_mass (m)", "v_mass (m/s)", "F_contact (N)", "time (s)"]:
        assert label in texts, (label, texts)
    assert not any("n_steps" in t or "n_rhs" in t or t.startswith("t_release") for t in texts)
    b = csv(tmp_path / "b.csv")
    # The release is marked at the first sample after the mass left the plate.
    first = int(np.argmax(b["in_contact"] == 0))
    assert b["t_release"][-1] <= b["time"][first] < b["t_release"][-1] + 1e-3 + 1e-12
    marks = [t for t in texts if t.startswith("in_contact → false")]
    assert len(marks) == 1, texts
    stamp = float(re.search(r"t = ([0-9.]+) s", marks[0]).group(1))
    assert abs(stamp - b["time"][first]) < 1e-4
    # The pendulum's angle and rate in the degrees its FMU declares for display.
    runner("simulate", "pendulum", "--plot", tmp_path / "p.png", "--out", tmp_path / "p.csv")
    assert png_size(tmp_path / "p.png") == (900, 3 * 210 + 40), "three panels: theta, omega, energy"
    runner("simulate", "pendulum", "--plot", tmp_path / "p.svg", "--out", tmp_path / "p.csv")
    assert {"theta (deg)", "omega (deg/s)", "energy (J)"} <= set(svg_texts(tmp_path / "p.svg"))


def test_overlay_and_phase_portrait(tmp_path):
    runner("simulate", "pendulum", "--overlay", "theta0=15deg,120deg", "--plot", tmp_path / "o.svg",
           "--out", tmp_path / "o.csv", "--output-interval", "0.01")
    o = csv(tmp_path / "o.csv")
    assert o.dtype.names[:3] == ("theta0", "time", "theta")
    assert np.unique(o["theta0"]).tolist() == [math.radians(15), math.radians(120)]
    assert len(o) == 2 * 1001
    texts = svg_texts(tmp_path / "o.svg")
    assert "theta0 = 15 deg" in texts and "theta0 = 120 deg" in texts
    runner("simulate", "pendulum", "--set", "theta0=120deg", "--plot-x", "theta", "--plot-vars", "omega",
           "--plot", tmp_path / "ph.svg", "--out", tmp_path / "ph.csv")
    texts = svg_texts(tmp_path / "ph.svg")
    assert "theta (deg)" in texts and "omega (deg/s)" in texts and "time (s)" not in texts


def test_animate_an_fmu_given_by_path_with_an_experiment_file(tmp_path):
    # A copy of the FMU outside the workspace, as a third-party FMU would be, and its [animate].
    copy = tmp_path / "thrower.fmu"
    shutil.copy(fmu("trebuchet"), copy)
    settings = tmp_path / "thrower.toml"
    settings.write_text((ROOT / "models" / "trebuchet" / "experiment.toml").read_text())
    runner("simulate", copy, "--output-interval", "0.01", "--out", tmp_path / "t.csv", "--plot-vars", "E_x",
           "--plot", tmp_path / "t.svg")
    landing = csv(tmp_path / "t.csv")["time"][-1]
    done = runner("animate", copy, "--experiment", settings, "--out", tmp_path / "t.gif", "--fps", "10", "--size", "500",
                  cwd=tmp_path)
    width, height, delays, loops = read_gif(tmp_path / "t.gif")
    assert (width, loops) == (500, True) and height >= 480
    # speed 0.25 at 10 frames per second: a frame every 0.025 s of motion, and the landing.
    n = math.floor(landing / 0.025 + 1e-9) + 1
    assert len(delays) == n + (1 if landing - (n - 1) * 0.025 > 1e-9 else 0), (len(delays), landing)
    assert set(delays) == {10}
    assert f"{len(delays)} frames" in done.stdout
    # Without an experiment file every point output is drawn with its path.
    runner("animate", copy, "--out", tmp_path / "plain.gif", "--stop-time", "0.5", cwd=tmp_path)
    assert read_gif(tmp_path / "plain.gif")[2]
    # An FMU without point coordinates, and a file that is not a GIF, are refused.
    err = runner("animate", "quarter_car", "--out", tmp_path / "q.gif", check=False).stderr
    assert "no point coordinates" in err, err
    err = runner("animate", "crank_slider", "--out", tmp_path / "c.png", check=False).stderr
    assert "must end in .gif" in err, err
    # Sizes and lengths that would exhaust memory or time are refused before the run.
    err = runner("animate", "crank_slider", "--out", tmp_path / "c.gif", "--size", "100000", check=False).stderr
    assert "480 to 4096 px" in err, err
    err = runner("animate", "crank_slider", "--out", tmp_path / "c.gif", "--stop-time", "1e5", check=False).stderr
    assert "more than the 20000 an animation may have" in err, err
    assert not (tmp_path / "c.gif").exists()


# What --plot FILE writes in each command that takes it, with a small run of each.
PLOTTING = {
    "simulate": ["simulate", "pendulum", "--stop-time", "2"],
    "sweep": ["sweep", "quarter_car", "--param", "speed=5:25:5", "--metric", "m=max(z_s)", "--stop-time", "2"],
    "compare": ["compare", "second_order", "--solvers", "euler,rk4,dopri5"],
}


def test_every_plot_option_writes_the_format_its_extension_names(tmp_path):
    for command, args in PLOTTING.items():
        # A PNG is a PNG (it once was an SVG in a file named .png): its size, ink, smooth curves.
        runner(*args, "--out", tmp_path / f"{command}.csv", "--plot", tmp_path / f"{command}.png")
        size = (900, 3 * 210 + 40) if command == "simulate" else (960, 600)
        check_png_figure(tmp_path / f"{command}.png", size)
        runner(*args, "--out", tmp_path / f"{command}.csv", "--plot", tmp_path / f"{command}.SVG")
        root = ET.parse(tmp_path / f"{command}.SVG").getroot()
        assert root.tag.endswith("svg") and (int(root.get("width")), int(root.get("height"))) == size
        # Any other extension is refused before the run, naming it and the ones there are.
        done = runner(*args, "--out", tmp_path / f"{command}_x.csv", "--plot", tmp_path / "p.pdf", check=False)
        assert done.returncode == 1, (command, done.stderr)
        assert "p.pdf" in done.stderr and ".svg or .png" in done.stderr and ".pdf is not one of them" in done.stderr, done.stderr
        assert not (tmp_path / "p.pdf").exists() and not (tmp_path / f"{command}_x.csv").exists()


def test_a_png_is_the_svg_rendered(tmp_path):
    # The PNG is rendered from the very SVG the .svg file holds: the same size, the curve
    # anti-aliased, and, on a line without anti-aliasing drawn here, the check fails.
    runner("simulate", "pendulum", "--plot-vars", "theta", "--out", tmp_path / "a.csv", "--plot", tmp_path / "a.svg")
    runner("simulate", "pendulum", "--plot-vars", "theta", "--out", tmp_path / "a.csv", "--plot", tmp_path / "a.png")
    root = ET.parse(tmp_path / "a.svg").getroot()
    check_png_figure(tmp_path / "a.png", (int(root.get("width")), int(root.get("height"))))
    stairs = np.full((100, 100, 3), 255, dtype=np.uint8)
    stairs[np.arange(100), np.arange(100) // 2] = (31, 119, 180)
    assert blend_levels(stairs, (31, 119, 180)) == 0
