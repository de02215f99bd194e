"""Local sweeps in the runner's sandbox worker processes (the default): a point whose FMU
crashes or hangs is a row whose status says so and the sweep goes on, as on the command line;
in_process=True gives the same numbers on threads; out/resume keep and continue a sweep's rows.
tests/c_fmu/faulty.c is the FMU that crashes (fault 1: SIGSEGV), hangs (3) or exits (4) in
fmi2DoStep at t = 0.31 on request; fault 0 is the Dahlquist equation x' = -k x, x(0) = 1,
stepped with its exact solution, so a good point's metric is exp(-k t) at the end."""

import math
import os
import time

import numpy as np
import pandas as pd
import pytest

import fmurunner
from fmurunner_helpers import EX4_METRICS, EX4_SPEEDS, faulty_fmu, fmu_path

RunnerError = fmurunner.RunnerError


@pytest.fixture(scope="module")
def faulty(tmp_path_factory):
    return faulty_fmu(tmp_path_factory.mktemp("faulty"))


def wait_for_rows(partial, process, rows=20, seconds=60):
    """Waits until the sweep `process` has written more than `rows` lines to `partial`, or has
    ended, or `seconds` have passed (the caller asserts which)."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and process.poll() is None:
        if partial.exists() and partial.read_text().count("\n") > rows:
            return
        time.sleep(0.02)


#: The metric of the sweeps to a file below: x(1) = exp(-k) for a good point.
X_END = {"x_end": "final(x)"}


def finished_sweep(faulty, tmp_path, params, **options):
    """A finished sweep of `faulty` over `params` to tmp_path/sweep.csv (metric X_END, to t = 1,
    2 threads, `options`): its CSV's path, its partial file's, the keyword arguments that resume
    it, its table and its CSV's bytes."""
    out = tmp_path / "sweep.csv"
    kwargs = dict(stop_time=1.0, threads=2, out=out, **options)
    full = fmurunner.sweep(faulty, params, X_END, **kwargs)
    return out, tmp_path / "sweep.csv.partial", kwargs, full, out.read_bytes()


def start_long_sweep(faulty, tmp_path, **popen):
    """A sweep of 3,000 points of `faulty` to tmp_path/sweep.csv started in another Python process
    (`popen`: Popen's options), long enough to be stopped while it writes: its CSV's path, its
    partial file's, its parameters, the keyword arguments that run it again, and the process
    (stderr piped)."""
    import subprocess
    import sys
    params = {"k": [0.01 * i for i in range(1, 3001)]}
    kwargs = dict(stop_time=10.0, output_interval=0.001, threads=2)
    out = tmp_path / "sweep.csv"
    script = (f"import fmurunner\nfmurunner.sweep({str(faulty)!r}, {params!r}, {X_END!r}, "
              f"out={str(out)!r}, **{kwargs!r})\n")
    child = subprocess.Popen([sys.executable, "-c", script], stderr=subprocess.PIPE, text=True, **popen)
    return out, tmp_path / "sweep.csv.partial", params, kwargs, child


def test_a_crashing_or_hanging_point_is_a_failed_row_and_the_sweep_goes_on(faulty):
    frame = fmurunner.sweep(faulty, {"fault": [0, 1, 0, 3, 4, 0]}, {"x_end": "final(x)"}, stop_time=1.0,
                            output_interval=0.01, threads=2, point_timeout=1.0)
    status = list(frame["status"])
    assert status[0] == status[2] == status[5] == "ok", status
    assert "crashed: SIGSEGV in fmi2DoStep at t = 0.31" in status[1], status[1]
    assert "timed out after 1 s in fmi2DoStep at t = 0.31" in status[3], status[3]
    assert "exit" in status[4] and "fmi2DoStep" in status[4], status[4]
    # The good points: x(1) = exp(-1) (the FMU's exact solution, to rounding over 100 steps).
    assert np.allclose(frame["x_end"][[0, 2, 5]], math.exp(-1.0), rtol=1e-12, atol=0)
    assert frame["x_end"][[1, 3, 4]].isna().all()


def test_a_point_past_worker_memory_is_a_failed_row_and_the_sweep_goes_on(faulty):
    """worker_memory limits each worker process: fault 5 leaks 10 MB per step (1 GB over the
    run), so its point runs out of a 256 MiB limit (the FMU's own malloc fails, unchecked, and
    it crashes, as the command line's test has it) while the point before it is computed."""
    frame = fmurunner.sweep(faulty, {"fault": [0, 5]}, {"x_end": "final(x)"}, start_values={"leak_mb": 10.0},
                            stop_time=1.0, output_interval=0.01, threads=1, worker_memory=256)
    status = list(frame["status"])
    assert status[0] == "ok" and frame["x_end"][0] == pytest.approx(math.exp(-1.0), rel=1e-12), status
    assert status[1].startswith("crashed: SIGSEGV in fmi2DoStep at t = "), status[1]


def test_isolated_and_in_process_give_the_same_bits():
    """The Ex. 4 sweep in worker processes and on threads of this process: same engine, so the
    same doubles; worker processes are the default."""
    isolated = fmurunner.sweep("quarter_car", {"speed": EX4_SPEEDS[:20]}, EX4_METRICS, threads=2)
    threads = fmurunner.sweep("quarter_car", {"speed": EX4_SPEEDS[:20]}, EX4_METRICS, threads=2, in_process=True)
    pd.testing.assert_frame_equal(isolated, threads, check_exact=True)


def test_options_that_do_not_fit_are_refused(faulty):
    with pytest.raises(RunnerError, match="drop in_process=True"):
        fmurunner.sweep(faulty, {"k": [1.0]}, {"x": "final(x)"}, in_process=True, point_timeout=1.0)
    with pytest.raises(RunnerError, match="worker_memory must be a whole number"):
        fmurunner.sweep(faulty, {"k": [1.0]}, {"x": "final(x)"}, worker_memory=0)
    with pytest.raises(RunnerError, match="point_timeout"):
        fmurunner.sweep(faulty, {"k": [1.0]}, {"x": "final(x)"}, point_timeout=-1.0)
    with pytest.raises(RunnerError, match="resume needs out"):
        fmurunner.sweep(faulty, {"k": [1.0]}, {"x": "final(x)"}, resume=True)


def test_a_sweep_to_a_file_resumes_where_it_stopped(faulty, tmp_path):
    """A sweep with out= writes its CSV; one cut short (its partial file holding the first rows)
    continues with resume=True, running only the points not in the file: the rows kept are read
    back (a value planted in them survives, so they were not run again), the others run."""
    params = {"k": [0.5, 1.0, 1.5, 2.0, 2.5, 3.0]}
    metrics = {"x_end": "final(x)"}
    out = tmp_path / "sweep.csv"
    full = fmurunner.sweep(faulty, params, metrics, stop_time=1.0, threads=2, out=out)
    on_disk = pd.read_csv(out, keep_default_na=False)
    assert on_disk["x_end"].tolist() == full["x_end"].tolist()
    assert np.allclose(full["x_end"], np.exp(-np.array(params["k"])), rtol=1e-12, atol=0)

    # Cut short after 2 rows (and half a third line, as a kill mid-write leaves it); plant 42.
    lines = out.read_text().splitlines(keepends=True)
    planted = lines[1].split(",")
    planted[1] = "42.0"
    (tmp_path / "sweep.csv.partial").write_text(lines[0] + ",".join(planted) + lines[2] + lines[3][:5])
    out.unlink()
    with pytest.raises(RunnerError, match="resume=True"):
        fmurunner.sweep(faulty, params, metrics, stop_time=1.0, threads=2, out=out)
    resumed = fmurunner.sweep(faulty, params, metrics, stop_time=1.0, threads=2, out=out, resume=True)
    assert resumed["x_end"][0] == 42.0
    assert resumed["x_end"][1:].tolist() == full["x_end"][1:].tolist()
    assert out.exists() and not (tmp_path / "sweep.csv.partial").exists()
    assert pd.read_csv(out)["x_end"].tolist() == resumed["x_end"].tolist()

    # A different sweep is not resumed from this record.
    (tmp_path / "sweep.csv.partial").write_text(lines[0] + lines[1])
    with pytest.raises(RunnerError, match="is not from this sweep"):
        fmurunner.sweep(faulty, {"k": [9.0, 8.0]}, metrics, stop_time=1.0, out=out, resume=True)


def test_a_partial_file_that_is_not_this_sweeps_rows_is_refused_and_a_torn_last_row_dropped(faulty, tmp_path):
    """resume=True reads the partial file's rows back as `runner sweep --resume` does: each row
    must be the row this sweep writes for its point (its parameter values, as many fields as the
    header, numbers or nothing for the metrics); a row that is not is refused with a RunnerError
    naming the file and the row, unless it is the file's last line, which a kill may have cut
    short (even inside a quoted status that holds a newline): that one is dropped and run again.
    Before, rows in another order or of other points were kept as they were (the returned table
    and the CSV gave their metrics to the wrong points), and other damage raised pandas' or
    numpy's errors."""
    params = {"k": [0.5, 1.0, 1.5, 2.0]}
    out, partial, kwargs, full, complete = finished_sweep(faulty, tmp_path, params)
    lines = complete.decode().splitlines(keepends=True)
    out.unlink()
    no_number = lines[1].split(",")
    no_number[1] = "abc"
    refused = {
        "rows in another order": (lines[0] + lines[2] + lines[1], "row 1 is not the row this sweep writes for point 1"),
        "another point's row": (lines[0] + lines[1] + "9.0,0.5,ok\n" + lines[3], "row 2 is not the row this sweep writes"),
        "a row with a field more": (lines[0] + lines[1].replace("\n", ",x\n") + lines[2], "row 1 is not the row"),
        "a metric that is no number": (lines[0] + ",".join(no_number) + lines[2], 'row 1 has the metric "abc", which is not a number'),
    }
    for what, (text, message) in refused.items():
        partial.write_text(text)
        with pytest.raises(RunnerError, match=message) as e:
            fmurunner.sweep(faulty, params, X_END, resume=True, **kwargs)
        assert str(partial) in str(e.value), what
    torn = {
        "a last row cut inside a quoted status": lines[0] + lines[1] + '1.0,,"crashed: SIGSEGV\nin fmi2Do',
        "a row past the last point": "".join(lines) + lines[1],
        "a last row of another point": lines[0] + lines[1] + "9.0,0.5,ok\n",
    }
    for what, text in torn.items():
        partial.write_text(text)
        resumed = fmurunner.sweep(faulty, params, X_END, resume=True, **kwargs)
        pd.testing.assert_frame_equal(resumed, full, check_exact=True, obj=what)
        assert out.read_bytes() == complete, what
        out.unlink()


def test_failed_rows_are_kept_by_a_resume_as_written(faulty, tmp_path):
    """The rows of failed points (their status, a message that may hold commas, quotes and
    newlines; their metrics empty) are read back by resume=True as they were written: the package
    writes and reads its rows through the engine's code for `runner sweep --out`, so the table
    and the file of a resumed sweep equal an uninterrupted one's, byte for byte. The points kept
    are not run again: a status planted in a kept row (spelled by the same engine) comes back."""
    params = {"fault": [0.0, 1.0, 0.0, 4.0, 0.0]}
    out, partial, kwargs, full, complete = finished_sweep(faulty, tmp_path, params, output_interval=0.01, point_timeout=5.0)
    assert list(full["status"] == "ok") == [True, False, True, False, True], list(full["status"])
    lines = complete.splitlines(keepends=True)
    out.unlink()
    # Cut after the failed point 1's row.
    partial.write_bytes(b"".join(lines[:3]))
    resumed = fmurunner.sweep(faulty, params, X_END, resume=True, **kwargs)
    pd.testing.assert_frame_equal(resumed, full, check_exact=True)
    assert out.read_bytes() == complete
    out.unlink()
    planted = 'crashed: planted, "quoted"\nover two lines'
    partial.write_bytes(lines[0] + lines[1] + fmurunner._engine.csv_line(["1.0", "", planted]))
    resumed = fmurunner.sweep(faulty, params, X_END, resume=True, **kwargs)
    assert resumed["status"][1] == planted and resumed["status"][3] == full["status"][3]
    assert pd.read_csv(out, keep_default_na=False)["status"][1] == planted


def test_a_partial_file_holding_every_row_is_put_in_place(faulty, tmp_path):
    """A sweep killed after its last row reached the partial file but before the file was renamed
    leaves every row there: resume=True runs nothing and puts the file in place as the CSV (it
    once returned the table and left the CSV unwritten, the partial file there for good)."""
    params = {"k": [0.5, 1.0, 1.5]}
    out = tmp_path / "sweep.csv"
    full = fmurunner.sweep(faulty, params, {"x_end": "final(x)"}, stop_time=1.0, threads=2, out=out)
    complete = out.read_bytes()
    out.rename(tmp_path / "sweep.csv.partial")
    resumed = fmurunner.sweep(faulty, params, {"x_end": "final(x)"}, stop_time=1.0, threads=2, out=out, resume=True)
    pd.testing.assert_frame_equal(resumed, full, check_exact=True)
    assert out.read_bytes() == complete and not (tmp_path / "sweep.csv.partial").exists()


def test_a_record_of_the_command_line_is_named_and_other_damage_refused(faulty, tmp_path):
    """resume=True beside a record the command line wrote (KEY = VALUE lines, not JSON) says so
    and how to continue it there; a record that is JSON but no object is refused as unreadable
    (it once raised AttributeError)."""
    out = tmp_path / "sweep.csv"
    (tmp_path / "sweep.csv.partial").write_text("k,x_end,status\n")
    record = tmp_path / "sweep.csv.sweep"
    record.write_text("# runner sweep: what produced the CSV beside this file; `runner sweep --resume` checks it\nfmu = f.fmu\n")
    with pytest.raises(RunnerError, match=r"record of a sweep of the command line, runner sweep: continue it there, with --out .* --resume"):
        fmurunner.sweep(faulty, {"k": [1.0]}, {"x_end": "final(x)"}, stop_time=1.0, out=out, resume=True)
    record.write_text("[1, 2]\n")
    with pytest.raises(RunnerError, match="cannot read .*sweep.csv.sweep.*it is not a JSON object"):
        fmurunner.sweep(faulty, {"k": [1.0]}, {"x_end": "final(x)"}, stop_time=1.0, out=out, resume=True)


def test_a_torn_header_is_started_again_and_another_first_line_refused(faulty, tmp_path):
    """A partial file holding part of the header (the file's first write, so no row was there; a
    kill before it was whole) is started again on resume=True, as `runner sweep --resume` does:
    nothing is lost. A first line that is not part of this sweep's header is refused, naming the
    file, and left as it was, even with no newline after it (it was started again, its content
    lost, before)."""
    params = {"k": [0.5, 1.0]}
    out, partial, kwargs, full, complete = finished_sweep(faulty, tmp_path, params)
    header = complete.split(b"\n")[0]
    for cut in (1, len(header) // 2, len(header)):
        out.unlink()
        partial.write_bytes(header[:cut])
        resumed = fmurunner.sweep(faulty, params, X_END, resume=True, **kwargs)
        pd.testing.assert_frame_equal(resumed, full, check_exact=True, obj=f"header cut at {cut}")
        assert out.read_bytes() == complete
    out.unlink()
    for other in (b"speed", header[:-1] + b"\n", b"k,y"):
        partial.write_bytes(other)
        with pytest.raises(RunnerError, match="does not start with this sweep's header") as e:
            fmurunner.sweep(faulty, params, X_END, resume=True, **kwargs)
        assert str(partial) in str(e.value) and partial.read_bytes() == other, other


def test_a_second_sweep_to_the_same_out_is_refused_and_a_killed_ones_lock_does_not_block_resume(faulty, tmp_path):
    """While a sweep (in another Python process) writes out=, a second to the same file, of this
    package or `runner sweep`, is refused at once naming the file, rather than interleaving its
    rows with the first's: both hold the record `<out>.sweep` under flock. The lock dies with
    the process: after a SIGKILL of the first, resume=True continues and the table is the one
    an uninterrupted sweep gives, bit for bit. And this package is refused while `runner sweep`
    writes the file. Before the lock, the second ran."""
    import signal
    import subprocess
    from fmurunner_helpers import RUNNER

    out, partial, params, kwargs, child = start_long_sweep(faulty, tmp_path)
    try:
        wait_for_rows(partial, child)
        assert child.poll() is None, "the first sweep ended before the second started"
        with pytest.raises(RunnerError, match=f"another sweep is writing {out} \\(it holds {out}.sweep locked\\)"):
            fmurunner.sweep(faulty, params, {"x_end": "final(x)"}, out=out, resume=True, **kwargs)
        cli = subprocess.run([str(RUNNER), "sweep", str(faulty), "--param", "k=1,2", "--metric", "x_end=final(x)",
                              "--out", str(out), "--resume"], capture_output=True, text=True, timeout=60)
        assert cli.returncode != 0 and f"another sweep is writing {out}" in cli.stderr, cli.stderr
        assert child.poll() is None, "the first sweep was still running while the others were refused"
    finally:
        child.send_signal(signal.SIGKILL)
        child.communicate(timeout=60)
    resumed = fmurunner.sweep(faulty, params, {"x_end": "final(x)"}, out=out, resume=True, **kwargs)
    whole = fmurunner.sweep(faulty, params, {"x_end": "final(x)"}, **kwargs)
    pd.testing.assert_frame_equal(resumed, whole, check_exact=True)

    # The other way round: `runner sweep` writing, this package refused.
    cli_out = tmp_path / "cli.csv"
    runner = subprocess.Popen([str(RUNNER), "sweep", str(faulty), "--param", "k=0.01:30:0.01", "--metric", "x_end=final(x)",
                               "--stop-time", "10", "--output-interval", "0.001", "--threads", "2", "--out", str(cli_out)],
                              stderr=subprocess.PIPE, text=True)
    try:
        wait_for_rows(tmp_path / "cli.csv.partial", runner)
        assert runner.poll() is None, "runner sweep ended before the second started"
        with pytest.raises(RunnerError, match=f"another sweep is writing {cli_out}"):
            fmurunner.sweep(faulty, params, {"x_end": "final(x)"}, out=cli_out, **kwargs)
        assert runner.poll() is None, "runner sweep was still running while this package was refused"
    finally:
        runner.send_signal(signal.SIGKILL)
        runner.communicate(timeout=60)


def test_sweep_results_carry_units():
    frame = fmurunner.sweep(fmu_path("quarter_car"), {"speed": [2.0, 4.0]}, ["peak=max(z_s)"], stop_time=1.0, threads=2)
    assert frame.attrs["units"]["speed"] == "m/s"
    assert frame.attrs["model_name"] == "quarter_car"


def test_a_sweep_interrupted_with_ctrl_c_keeps_its_rows_and_resumes(faulty, tmp_path):
    """A sweep to a file in another Python process, sent SIGINT (Ctrl-C) once rows are on disk:
    it stops with KeyboardInterrupt, leaving the partial file and no CSV; resume=True runs the
    rest, and the whole table is the one an uninterrupted sweep gives, bit for bit. Its Python
    gets SIGINT's default action to start from: a test command started in the background by a
    shell inherits SIGINT ignored, and a Python started so installs no KeyboardInterrupt handler
    (it then ran to the end and exited 0)."""
    import signal
    out, partial, params, kwargs, child = start_long_sweep(
        faulty, tmp_path, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    wait_for_rows(partial, child)
    assert child.poll() is None, "the sweep ended before it could be interrupted"
    child.send_signal(signal.SIGINT)
    _, stderr = child.communicate(timeout=60)
    assert child.returncode != 0 and "KeyboardInterrupt" in stderr, stderr
    assert partial.exists() and not out.exists()
    kept = partial.read_text().count("\n") - 1
    assert 20 <= kept < 3000, kept
    resumed = fmurunner.sweep(faulty, params, {"x_end": "final(x)"}, out=out, resume=True, **kwargs)
    whole = fmurunner.sweep(faulty, params, {"x_end": "final(x)"}, **kwargs)
    pd.testing.assert_frame_equal(resumed, whole, check_exact=True)


@pytest.mark.parametrize("in_process", [True, False])
def test_rows_are_not_handed_again_after_writing_them_failed(in_process):
    """A sweep to a file hands its finished rows to a writer as they come; when the writer fails
    part way (Ctrl-C while it writes, a full disk) it may have written some of them, so it must
    not be handed the same rows again at the end: the file would hold them twice, every later
    row in another point's place (what tests/python's Ctrl-C test caught now and then). Here the
    writer fails at its first call, while points still run: it is called once, and the sweep
    raises its error."""

    from fmurunner import _engine, _worker

    # Long enough (a second or more) that the writer is first called while points still run.
    path, grid, sets = fmurunner._resolve("quarter_car", "sweep", 1.0, 0.01, None, None)
    spec, n, _, _ = _engine.plan_sweep(path, grid, sets, [("speed", [1.0 + 0.02 * s for s in range(2000)])], ["p=max(z_s)"])
    calls = []

    def on_rows(first, data, failures):
        calls.append(first)
        raise OSError("no space left on device")

    with pytest.raises(RunnerError, match="writing the finished rows failed: OSError: no space left on device"):
        if in_process:
            _engine.Model(path).run_points(spec, 0, n, 1, on_rows)
        else:
            _engine.run_points_isolated(path, spec, 0, n, 1, _worker.command("sweep"), on_rows=on_rows)
    assert calls == [0], calls
