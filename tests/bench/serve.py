"""What `runner serve` costs. (1) In the browser, per lab model at its default experiment: the
time from a changed parameter (a slider moved by a key press; the page's input event) to the
plots drawn with the new run on their canvases, and to the browser's next frame (which shows
them; the target is on this one), by `performance.now()` in the page, over --changes changes
each waiting for the last. Target: a median under 100 ms. (2) Per
simulate request, outside the browser: the request's wall time (HTTP, the run in the model's warm
worker, JSON) with the run's own time in the worker (`run_ms`), against the wall time of the same
run as a whole `runner simulate --in-process` process (start, unpack, load, run, CSV), fastest of
--repeats interleaved rounds. The machine is shared and noisy: the load average is printed."""

import argparse
import json
import os
import pathlib
import statistics
import sys
import time
import urllib.request

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests" / "serve"))
sys.path.insert(0, str(ROOT / "tests" / "bench"))

from serve_tools import RUNNER, Server, lab_models  # noqa: E402
from validate import wall  # noqa: E402

TARGET_MS = 100.0


def browser_latencies(server, models, changes):
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    options = webdriver.ChromeOptions()
    for argument in ["--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1400,1000", "--disable-gpu"]:
        options.add_argument(argument)
    driver = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=options)
    js = driver.execute_script

    def wait(condition, seconds=30):
        deadline = time.monotonic() + seconds
        while not js("return " + condition):
            if time.monotonic() > deadline:
                sys.exit(f"timed out waiting for {condition}")
            time.sleep(0.01)

    found = {}
    try:
        for model in models:
            driver.get(f"{server.url}/#{model}")
            wait(f"window.lab && lab.model && lab.model.id === '{model}' && lab.runs >= 1 && !lab.busy")
            name = js("""return lab.model.variables.find(v => v.settable && v.causality === 'parameter' && v.kind === 'Real' && v.start
                && !['solver', 'fixed_step', 'abs_tol', 'max_step'].includes(v.name)).name""")
            slider = driver.find_element(By.ID, f"slider-{name}")
            for k in range(changes):
                runs = js("return lab.runs")
                # Up and down by a step, so the value stays near the default.
                slider.send_keys(Keys.ARROW_RIGHT if k % 2 == 0 else Keys.ARROW_LEFT)
                wait(f"lab.runs > {runs} && !lab.busy && lab.latency.length >= {k + 1}")
            samples = js("return lab.latency")
            drawn = js("return lab.drawn")
            points = js("return lab.result.time.length")
            found[model] = (name, points, samples, drawn)
    finally:
        driver.quit()
    return found


def request_ms(server, model):
    """(wall ms of one simulate request, the run's ms in the worker)."""
    request = urllib.request.Request(f"{server.url}/api/models/{model}/simulate", data=b"{}", headers={"Content-Type": "application/json"})
    start = time.perf_counter()
    with urllib.request.urlopen(request) as response:
        body = response.read()
    seconds = time.perf_counter() - start
    return seconds * 1e3, json.loads(body)["run_ms"]


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--changes", type=int, default=10, help="slider changes per model (default 10)")
    parser.add_argument("--repeats", type=int, default=5, help="interleaved rounds of the request timing (default 5)")
    parser.add_argument("models", nargs="*", help="models (default: every lab model)")
    args = parser.parse_args()
    models = args.models or lab_models()
    print(f"load average before: {' '.join(f'{x:.1f}' for x in os.getloadavg())} ({os.cpu_count()} cores)")
    server = Server(*models)
    try:
        latencies = browser_latencies(server, models, args.changes)
        best = {m: [float("inf")] * 3 for m in models}
        for _ in range(args.repeats):
            for m in models:
                wall_ms, run_ms = request_ms(server, m)
                if wall_ms < best[m][0]:
                    best[m][0], best[m][1] = wall_ms, run_ms
                best[m][2] = min(best[m][2], 1e3 * wall([RUNNER, "simulate", m, "--in-process", "--out", "/dev/null"]))
    finally:
        server.stop()
    print(f"load average after:  {' '.join(f'{x:.1f}' for x in os.getloadavg())}")
    print(f"\nchanged parameter to updated plot, in headless Chromium ({args.changes} changes per model, release build)\n")
    print(f"| model | parameter | samples | drawn, median (ms) | next frame, median (ms) | next frame, max (ms) | under {TARGET_MS:.0f} ms |")
    print("|---|---|---|---|---|---|---|")
    missed = False
    for m, (name, points, samples, drawn) in latencies.items():
        median = statistics.median(samples)
        met = median < TARGET_MS
        missed |= not met
        print(f"| {m} | {name} | {points} | {statistics.median(drawn):.1f} | {median:.1f} | {max(samples):.1f} | {'met' if met else 'MISSED'} |")
    print(f"\none simulate request against one `runner simulate --in-process` process (fastest of {args.repeats})\n")
    print("| model | request (ms) | of it the run in the worker (ms) | server overhead (ms) | runner simulate --in-process (ms) |")
    print("|---|---|---|---|---|")
    for m, (wall_ms, run_ms, cli_ms) in best.items():
        print(f"| {m} | {wall_ms:.1f} | {run_ms:.1f} | {wall_ms - run_ms:.1f} | {cli_ms:.1f} |")
    sys.exit(1 if missed else 0)


if __name__ == "__main__":
    main()
