"""The JSON API of `runner serve`, over HTTP with urllib: every endpoint against the command line
it stands for (`runner simulate`, `runner sweep`, the FMU file, modelDescription.xml read here),
compared to the bit; every refusal with its status and a JSON error naming the problem; and the
Origin and Host checks that keep other web pages from driving the server."""

import json
import math
import subprocess
import zipfile

import pytest

# server: the session's server of every lab model (no conftest.py here: tests/fmpy's modules
# import theirs by the name conftest, which a second one in the same run would take).
from serve_tools import MAX_POINTS, FMU_DIR, ROOT, Server, description, lab_models, read_csv, runner, server, simulate_csv, wait_for  # noqa: F401

# The solver controls every toolkit FMU has: parameters, but not the model's.
CONTROLS = {"solver", "fixed_step", "abs_tol", "max_step", "n_steps", "n_rhs"}


def changed_parameter(details):
    """A `NAME=VALUE UNIT` change of the model's first Real parameter with a non-zero start, by
    1 % in its display unit (so the server converts the unit as `--set` does)."""
    for v in details["variables"]:
        if v["settable"] and v["causality"] == "parameter" and v["kind"] == "Real" and v["start"] and v["name"] not in CONTROLS:
            d = v["display"]
            if d:
                return v["name"], f"{round((d['factor'] * v['start'] + d['offset']) * 1.01, 9)!r} {d['unit']}"
            return v["name"], repr(v["start"] * 1.01)
    pytest.fail(f"{details['id']} has no Real parameter to change")


def same(a, b):
    """Equal to the bit, NaN (JSON null) equal to NaN."""
    if a is None or b is None or (isinstance(a, float) and math.isnan(a)):
        return (a is None or math.isnan(a)) and (b is None or math.isnan(b))
    return a == b


def test_the_model_list_names_every_lab_model_with_its_description(server):
    models = server.json("/api/models")
    assert [m["id"] for m in models] == lab_models()
    for m in models:
        root = description(m["id"])
        assert m["description"] == root.get("description"), m["id"]
        assert m["name"] == root.get("modelName")
    animated = {m["id"] for m in models if m["animation"]}
    # Every mechanism and the trebuchet have an [animate] scene; the quarter car has no points.
    assert {"trebuchet", "crank_slider", "crank_rocker", "double_rocker", "offset_crank_slider", "inverted_crank_slider"} <= animated
    assert "quarter_car" not in animated


@pytest.mark.parametrize("model", lab_models())
def test_variables_carry_the_units_ranges_and_starts_of_the_description(server, model):
    """Every variable's unit, display unit (with its factor), min, max and start as
    modelDescription.xml declares them, read here with ElementTree."""
    details = server.json(f"/api/models/{model}")
    root = description(model)
    factors = {(u.get("name"), d.get("name")): (float(d.get("factor", 1)), float(d.get("offset", 0)))
               for u in root.iter("Unit") for d in u.iter("DisplayUnit")}
    by_name = {v["name"]: v for v in details["variables"]}
    for sv in root.iter("ScalarVariable"):
        if sv.get("causality") == "independent":
            continue
        v = by_name[sv.get("name")]
        (element,) = list(sv)
        assert v["kind"] == element.tag, sv.get("name")
        number = lambda key: float(element.get(key)) if element.get(key) is not None else None
        assert v["min"] == number("min") and v["max"] == number("max"), sv.get("name")
        if element.tag == "Real":
            assert v["start"] == number("start") and v["unit"] == element.get("unit"), sv.get("name")
            shown = element.get("displayUnit")
            if shown:
                factor, offset = factors[(element.get("unit"), shown)]
                assert v["display"] == {"unit": shown, "factor": factor, "offset": offset}, sv.get("name")
            else:
                assert v["display"] is None, sv.get("name")
        assert v["settable"] == (sv.get("causality") in ("parameter", "input") and element.tag != "String"
                                 and sv.get("variability") != "constant"), sv.get("name")


@pytest.mark.parametrize("model", lab_models())
def test_a_run_equals_runner_simulate_to_the_bit(server, tmp_path, model):
    """The API's run with a changed parameter (in its display unit) and `runner simulate
    --set` of the same: every output at every time equal to the bit, and the API's CSV
    byte for byte the file `runner simulate --out` writes."""
    details = server.json(f"/api/models/{model}")
    name, value = changed_parameter(details)
    result = server.json(f"/api/models/{model}/simulate", {"set": {name: value}})
    expected = simulate_csv(tmp_path, model, [f"{name}={value}"])
    header, rows = read_csv(expected)
    assert header == ["time", *result["names"][:result["outputs"]]]
    assert len(rows) == len(result["time"]) > 1
    for i, row in enumerate(rows):
        assert float(row[0]) == result["time"][i]
        for c, text in enumerate(row[1:]):
            assert same(float(text), result["columns"][c][i]), f"{header[c + 1]} at t = {row[0]}: {text} != {result['columns'][c][i]!r}"
    code, headers, body = server.call(f"/api/models/{model}/simulate", {"set": {name: value}, "format": "csv"})
    assert code == 200 and headers["Content-Type"].startswith("text/csv")
    assert body.decode() == expected


def test_a_run_answers_the_columns_asked_for(server):
    """`variables` picks the columns answered (the page asks for what it draws); `recorded`
    names them all, the outputs first."""
    full = server.json("/api/models/pendulum/simulate", {})
    some = server.json("/api/models/pendulum/simulate", {"variables": ["omega", "theta"]})
    assert some["recorded"] == full["recorded"] == full["names"] and some["names"] == ["omega", "theta"]
    assert some["columns"] == [full["columns"][full["names"].index(n)] for n in ["omega", "theta"]] and some["time"] == full["time"]
    assert "'thta' is not recorded" in error(server, "/api/models/pendulum/simulate", 400, {"variables": ["thta"]})


def test_events_are_the_changes_of_the_discrete_outputs(server):
    """The trebuchet's regimes (to 4, the flight) and its landing: an event wherever `regime`
    changes between samples, named by its new value."""
    result = server.json("/api/models/trebuchet/simulate", {})
    regime = result["columns"][result["names"].index("regime")]
    changes = [i for i in range(1, len(regime)) if regime[i] != regime[i - 1]]
    assert [e["index"] for e in result["events"] if "regime" in e["text"]] == changes
    assert [e["text"] for e in result["events"] if "regime" in e["text"]] == [f"regime → {regime[i]:g}" for i in changes]
    assert len(changes) >= 2 and regime[-1] == 4
    assert result["ended_early"] and "landed" in result["ended_early"]


def test_a_sweep_reports_its_progress_and_equals_runner_sweep(server, tmp_path):
    param, metric = "speed=5:30:2.5", "transmissibility=max(z_s)/max(z_r)"
    started = server.json("/api/models/quarter_car/sweep", {"param": [param], "metric": [metric]}, status=202)
    assert started["total"] == 11 and started["params"] == ["speed"] and started["metrics"] == ["transmissibility"]
    seen = []

    def finished():
        report = server.json(f"/api/sweeps/{started['job']}")
        seen.append(report["done"])
        return report if report["finished"] else None

    report = wait_for(finished, 120, "the sweep finishing")
    assert seen == sorted(seen) and report["done"] == 11 and report["error"] is None
    assert [r["point"][0] for r in report["rows"]] == [5 + 2.5 * k for k in range(11)]
    later = server.json(f"/api/sweeps/{started['job']}?from=9")
    assert later["from"] == 9 and len(later["rows"]) == 2
    out = tmp_path / "sweep.csv"
    runner("sweep", "quarter_car", "--param", param, "--metric", metric, "--out", out)
    code, headers, body = server.call(f"/api/sweeps/{started['job']}/csv")
    assert code == 200 and body.decode() == out.read_text()


def test_the_scene_is_the_animation_of_runner_animate(server, tmp_path):
    """The trebuchet's scene at [animate]'s 10 ms: the projectile E where `runner simulate` at
    that interval puts it, to the bit; the links and trails of experiment.toml."""
    scene = server.json("/api/models/trebuchet/scene", {})
    names = [p["name"] for p in scene["points"]]
    assert {"A", "B", "C", "D", "E"} <= set(names)
    n = len(scene["time"])
    assert len(scene["views"]) == n and len(scene["stamps"]) == n and scene["fps"] == 25
    assert scene["frames"][0] == 0 and scene["frames"][-1] == n - 1
    assert [[names[i] for i in link["points"]] for link in scene["links"]] == [["A", "C"], ["B", "C", "D"], ["D", "E"]]
    out = tmp_path / "t.csv"
    runner("simulate", "trebuchet", "--output-interval", "0.01", "--output-variable", "E_x", "--output-variable", "E_y", "--out", out)
    _, rows = read_csv(out.read_text())
    e = scene["points"][names.index("E")]
    assert [float(r[0]) for r in rows] == scene["time"]
    assert [float(r[1]) for r in rows] == e["x"] and [float(r[2]) for r in rows] == e["y"]
    # The sling DE is drawn until release (regime 4), not after.
    assert scene["links"][2]["shown"][0] and not scene["links"][2]["shown"][-1]
    crank = server.json("/api/models/crank_slider/scene", {})
    o = next(p for p in crank["points"] if p["name"] == "O")
    assert o["fixed"] and set(o["x"]) == {0.0} and set(o["y"]) == {0.0}


def test_the_fmu_download_is_the_file(server):
    code, headers, body = server.call("/api/models/pendulum/fmu")
    assert code == 200 and body == (FMU_DIR / "pendulum.fmu").read_bytes()
    assert headers["Content-Disposition"] == 'attachment; filename="pendulum.fmu"'


def test_the_page_and_its_scripts_are_served_by_the_runner(server):
    for path, kind in [("/", "text/html"), ("/app.js", "text/javascript"), ("/app.css", "text/css"),
                       ("/uplot/uPlot.iife.min.js", "text/javascript"), ("/uplot/uPlot.min.css", "text/css"), ("/uplot/LICENSE", "text/plain")]:
        code, headers, body = server.call(path)
        assert code == 200 and headers["Content-Type"].startswith(kind) and body, path
    _, _, page = server.call("/")
    # Nothing from elsewhere: the page works offline.
    assert b"http://" not in page and b"https://" not in page


def error(server, path, status, body=None, method=None, headers=None, raw=None):
    """The JSON error of a refused request, checked to have `status`."""
    code, response_headers, data = server.call(path, body, method, headers, raw)
    assert code == status, f"{path}: {code} {data[:300]!r}"
    assert response_headers["Content-Type"] == "application/json"
    answer = json.loads(data)
    assert answer["status"] == status
    return answer["error"]


def test_bad_requests_get_a_4xx_naming_the_problem(server):
    assert "no model 'quater_car'" in error(server, "/api/models/quater_car", 404) and "quarter_car" in error(server, "/api/models/x", 404)
    assert "nothing at /etc/passwd" in error(server, "/etc/passwd", 404)
    # Only the embedded page is served: no path reaches the file system.
    assert "nothing at" in error(server, "/../../etc/passwd", 404) and "nothing at" in error(server, "/uplot/../../Cargo.toml", 404)
    assert "takes POST" in error(server, "/api/models/quarter_car/simulate", 405)
    assert "PUT is not allowed" in error(server, "/api/models", 405, method="PUT", raw=b"{}")
    assert "JSON" in error(server, "/api/models/quarter_car/simulate", 415, raw=b"{}", headers={"Content-Type": "text/plain"})
    assert "not the JSON expected" in error(server, "/api/models/quarter_car/simulate", 400, raw=b"{not json")
    assert "unknown field `path`" in error(server, "/api/models/quarter_car/simulate", 400, {"path": "/tmp/x.fmu"})
    assert "k_ss" in error(server, "/api/models/quarter_car/simulate", 400, {"set": {"k_ss": 1}})
    assert "'k_s' cannot be given in 'deg'" in error(server, "/api/models/quarter_car/simulate", 400, {"set": {"k_s": "10 deg"}})
    assert "format 'xml'" in error(server, "/api/models/quarter_car/simulate", 400, {"format": "xml"})
    assert "samples, more than the 200000" in error(server, "/api/models/quarter_car/simulate", 400, {"stop_time": 1e4})
    # A String may name a file on the server (the road's table): never set from a request.
    assert "only numbers and Booleans" in error(server, "/api/models/road/simulate", 400, {"set": {"table": "/etc/passwd"}})
    assert "more than the 65536 bytes" in error(server, "/api/models/quarter_car/simulate", 413, raw=b" " * 70000)
    assert "has no animation" in error(server, "/api/models/quarter_car/scene", 404, {})
    assert f"more than the {MAX_POINTS}" in error(server, "/api/models/quarter_car/sweep", 400, {"param": ["speed=1:1000:1"], "metric": ["m=max(z_s)"]})
    assert "nothing to sweep" in error(server, "/api/models/quarter_car/sweep", 400, {"param": [], "metric": ["m=max(z_s)"]})
    assert "no metric" in error(server, "/api/models/quarter_car/sweep", 400, {"param": ["speed=1,2"], "metric": []})
    assert "no sweep 999" in error(server, "/api/sweeps/999", 404)
    assert "from must be a row number" in error(server, "/api/sweeps/1?from=x", 400)


def test_one_sweep_at_a_time_and_a_sweep_can_be_cancelled(server):
    started = server.json("/api/models/quarter_car/sweep", {"param": ["speed=1:50:0.5"], "metric": ["m=max(z_s)"]}, status=202)
    assert "still running" in error(server, "/api/models/pendulum/sweep", 429, {"param": ["L=1,2"], "metric": ["m=max(theta)"]})
    assert server.json(f"/api/sweeps/{started['job']}", method="DELETE") == {"cancelled": True}
    report = wait_for(lambda: (r := server.json(f"/api/sweeps/{started['job']}"))["finished"] and r, 60, "the cancelled sweep ending")
    assert report["error"] and report["done"] < report["total"]


def test_requests_from_other_origins_are_refused(server):
    port = server.url.rsplit(":", 1)[1]
    own = {"Origin": server.url}
    assert server.json("/api/models", headers=own)
    assert server.json("/api/models/pendulum/simulate", {}, headers=own)["time"]
    for origin in ["http://evil.example", f"http://127.0.0.1:{int(port) + 1}", "null", f"https://127.0.0.1:{port}"]:
        assert "another origin" in error(server, "/api/models/pendulum/simulate", 403, {}, headers={"Origin": origin}), origin
        assert "another origin" in error(server, "/api/models", 403, headers={"Origin": origin}), origin
    # A DNS name rebound to 127.0.0.1 reaches the server with its own Host: refused too.
    assert "not this server's" in error(server, "/api/models", 403, headers={"Host": f"evil.example:{port}"})
    assert "cross-site" in error(server, "/api/models", 403, headers={"Sec-Fetch-Site": "cross-site"})


def test_a_run_past_the_point_timeout_fails_and_the_server_goes_on():
    """--point-timeout stops a run in its worker; the next run gets a fresh worker."""
    s = Server("quarter_car", "--point-timeout", "0.05")
    try:
        message = error(s, "/api/models/quarter_car/simulate", 400, {"stop_time": 150})
        assert "0.05" in message and "time" in message, message
        assert s.json("/api/models/quarter_car/simulate", {"stop_time": 0.1, "output_interval": 0.01})["time"][-1] == 0.1
    finally:
        assert s.stop() == 0


def test_listening_beyond_this_machine_is_warned_about():
    s = Server("pendulum", "--host", "127.0.0.1")
    try:
        assert s.json("/api/models")[0]["id"] == "pendulum"
    finally:
        assert s.stop() == 0
    assert "warning: listening on" in s.stderr and "anyone who can reach this address" in s.stderr


def faulty_fmu(directory):
    """tests/c_fmu/faulty.c built into an FMU: it segfaults (fault=1) or hangs (fault=3) on
    request, as a third-party FMU may."""
    source = ROOT / "tests" / "c_fmu"
    binary = directory / "faulty.so"
    subprocess.run(["cc", "-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-o", binary, source / "faulty.c", "-lm"], check=True)
    fmu = directory / "faulty.fmu"
    with zipfile.ZipFile(fmu, "w") as z:
        z.write(source / "faulty.xml", "modelDescription.xml")
        z.write(binary, "binaries/linux64/faulty.so")
    return fmu


def test_an_fmu_that_crashes_or_hangs_costs_its_request_not_the_server(tmp_path):
    s = Server(faulty_fmu(tmp_path), "--point-timeout", "2")
    try:
        assert "SIGSEGV" in error(s, "/api/models/faulty/simulate", 400, {"set": {"fault": 1}})
        assert "2 s" in error(s, "/api/models/faulty/simulate", 400, {"set": {"fault": 3}})
        # The next run gets a fresh worker and the server answers as before.
        assert s.json("/api/models/faulty/simulate", {})["time"]
        started = s.json("/api/models/faulty/sweep", {"param": ["fault=0,1"], "metric": ["end=final(x)"]}, status=202)
        report = wait_for(lambda: (r := s.json(f"/api/sweeps/{started['job']}"))["finished"] and r, 60, "the faulty sweep")
        assert [r["status"] == "ok" for r in report["rows"]] == [True, False] and "SIGSEGV" in report["rows"][1]["status"]
    finally:
        assert s.stop() == 0
