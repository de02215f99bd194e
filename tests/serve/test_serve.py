"""The lab page of `runner serve` in a real browser (headless Chromium through Debian's
chromedriver, driven by Selenium; no driver is downloaded). For every lab model: load the page,
change a parameter as a user does (a slider moved by a key press), check that the plotted values
are `runner simulate`'s for that value (to the bit, converted to the display unit by FMI's rule),
run a short sweep, play the animation where there is one, and check screenshots are not blank.
Skipped, saying why, when Chromium or its driver is missing (tests/run installs them when it
can)."""

import io
import json
import pathlib
import shutil
import time

import pytest

from serve_tools import lab_models, read_csv, server, simulate_csv, wait_for  # noqa: F401 (server: the fixture)

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
CHROMEDRIVER = shutil.which("chromedriver") or "/usr/bin/chromedriver"
CONTROLS = ["solver", "fixed_step", "abs_tol", "max_step", "n_steps", "n_rhs"]

if not (pathlib.Path(CHROMIUM).is_file() and pathlib.Path(CHROMEDRIVER).is_file()):
    pytest.skip(f"Chromium ({CHROMIUM}) or chromedriver ({CHROMEDRIVER}) is missing: "
                "install Debian's chromium and chromium-driver (tests/run does when it can)", allow_module_level=True)

webdriver = pytest.importorskip("selenium.webdriver")
from PIL import Image  # noqa: E402
from selenium.webdriver.chrome.service import Service  # noqa: E402
from selenium.webdriver.common.by import By  # noqa: E402
from selenium.webdriver.common.keys import Keys  # noqa: E402


@pytest.fixture(scope="module")
def browser():
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for argument in ["--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1400,1000", "--disable-gpu"]:
        options.add_argument(argument)
    # An explicit driver: Selenium Manager never looks for (or downloads) one.
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    driver.set_script_timeout(30)
    yield driver
    driver.quit()


def non_blank(png, what):
    """Checks a screenshot shows something: some pixels away from its background colour, in
    more than two colours (a blank or one-colour panel fails)."""
    image = Image.open(io.BytesIO(png)).convert("RGB")
    colours = image.getcolors(maxcolors=1 << 20)
    background = max(colours)[1]
    drawn = sum(n for n, c in colours if sum(abs(a - b) for a, b in zip(c, background)) > 60)
    share = drawn / (image.width * image.height)
    assert len(colours) > 3 and share > 0.005, f"{what} looks blank: {len(colours)} colours, {share:.2%} drawn"


def js(browser, script):
    return browser.execute_script(script)


def idle(browser, runs):
    """Waits until the page has drawn `runs` runs and has none in flight."""
    wait_for(lambda: js(browser, f"return window.lab && lab.runs >= {runs} && !lab.busy"), 30, f"run {runs} drawn")
    error = js(browser, "return lab.error")
    assert error is None, error


@pytest.mark.parametrize("model", lab_models())
def test_every_lab_model_in_the_browser(server, browser, tmp_path, model):
    browser.get(f"{server.url}/#{model}")
    wait_for(lambda: js(browser, f"return window.lab && lab.model && lab.model.id === '{model}'"), 30, "the model's page")
    idle(browser, 1)

    # Change a parameter as a user does: its slider, one key press to the right.
    name = js(browser, f"""return lab.model.variables.find(v => v.settable && v.causality === 'parameter' && v.kind === 'Real'
        && v.start && !{json.dumps(CONTROLS)}.includes(v.name)).name""")
    browser.find_element(By.ID, f"slider-{name}").send_keys(Keys.ARROW_RIGHT)
    wait_for(lambda: js(browser, f"return '{name}' in lab.changed"), 10, "the change taken")
    idle(browser, 2)
    changed = js(browser, "return lab.changed")
    field = browser.find_element(By.ID, f"field-{name}").get_attribute("value")
    assert changed[name].split()[0] == field

    # What is plotted is `runner simulate --set` of the same value, in the display units.
    plotted = js(browser, "return lab.plots.map(p => [p.series[1].label, Array.from(p.data[0]), Array.from(p.data[1])])")
    variables = {v["name"]: v for v in js(browser, "return lab.model.variables")}
    header, rows = read_csv(simulate_csv(tmp_path, model, [f"{k}={v}" for k, v in changed.items()]))
    assert plotted and len(plotted) == len(js(browser, "return lab.model.plotted"))
    times = [float(r[0]) for r in rows]
    for label, t, y in plotted:
        assert t == times, f"{label}: the plotted times are not runner simulate's"
        display = variables[label]["display"]
        column = [float(r[header.index(label)]) for r in rows]
        shown = [display["factor"] * x + display["offset"] if display else x for x in column]
        assert y == shown, f"{label}: the plotted values are not runner simulate's"
    non_blank(browser.find_element(By.ID, "plots").screenshot_as_png, f"{model}'s plots")
    non_blank(browser.find_element(By.ID, "phase").screenshot_as_png, f"{model}'s phase plot")

    # A short sweep of the same parameter: three points around its start (SI, as runner sweep).
    start = variables[name]["start"]
    # The parameter chosen as a user does (its change event sets the range and the unit).
    js(browser, f"""const select = document.getElementById('sweep-param');
        select.value = '{name}';
        select.dispatchEvent(new Event('change'));
        document.getElementById('sweep-from').value = '{start!r}';
        document.getElementById('sweep-to').value = '{start * 1.1!r}';
        document.getElementById('sweep-step').value = '{start * 0.05!r}';""")
    unit = variables[name].get("unit")
    assert browser.find_element(By.ID, "sweep-unit").text == (f"({unit}, SI as in runner sweep)" if unit else "")
    browser.find_element(By.ID, "sweep-run").click()
    report = wait_for(lambda: js(browser, "return lab.sweep && lab.sweep.finished && lab.sweep"), 60, "the sweep")
    assert report["error"] is None and len(report["rows"]) == report["total"] >= 2, report
    assert all(r["status"] == "ok" for r in report["rows"]), report["rows"]
    assert report["peak"]["y"] == max(r["metrics"][0] for r in report["rows"])
    non_blank(browser.find_element(By.ID, "sweep-plot").screenshot_as_png, f"{model}'s sweep plot")

    if js(browser, "return lab.model.animation"):
        wait_for(lambda: js(browser, "return lab.scene !== null"), 30, "the animation's scene")
        browser.find_element(By.ID, "play").click()
        wait_for(lambda: js(browser, "return lab.frame > 0"), 5, "the animation advancing")
        if js(browser, "return lab.playing"):
            # Pause holds the frame.
            browser.find_element(By.ID, "play").click()
            held = js(browser, "return [lab.playing, lab.frame]")
            time.sleep(0.2)
            assert held == [False, js(browser, "return lab.frame")], "pause did not hold the frame"
        non_blank(browser.find_element(By.ID, "animation").screenshot_as_png, f"{model}'s animation")
    browser.save_screenshot(str(tmp_path / f"{model}.png"))
