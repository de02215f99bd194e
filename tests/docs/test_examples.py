"""Examples that cannot go stale: every command example of README.md and the guide (docs/src) runs
here, its output checked against the text the reader sees.

- A ```console block holds commands, each on a line starting with `$ ` (a line ending in `\\`
  continues on the next), each followed by its expected output: stdout and stderr together, as a
  terminal shows them. Lines are compared after stripping trailing blanks; a line `...` stands for
  any number of lines (none included), and `[..]` within a line for any text on that line. A
  command must exit 0, unless its output ends with a line `? N`: then N is its exit code.
- A ```python block runs as a script with the test venv's Python; it must not raise.
- Blocks of one page run in order in one scratch directory outside the repository (so a page's
  walkthrough can build on its earlier steps), whose `target` and `systems` link to this
  checkout's, with the runner (target/release) and the venv first on PATH and CARGO_TARGET_DIR
  set to this checkout's target (the FMUs are built once, by tests/run, before this runs).
- A block of another language that holds commands (```sh, ```bash, ```shell) is refused: write
  it as a console block. The few examples that cannot run here are listed in NOT_RUN, each with
  the reason; a NOT_RUN entry that matches no example fails, so the list cannot rot either.
  A block that uses the Reference FMUs (../shared/reference-fmus beside the checkout) is skipped
  where they are not installed.
- `cargo run --release -p runner -- ARGS` runs as `runner ARGS`: the binary tests/run has just
  built with that very command, run in the scratch directory rather than the repository.

After a change of behaviour, DOCS_BLESS=1 writes each command's actual output into its page in
place of the expected one (then review the diff, and put `...` back where output is elided).
"""

import os
import pathlib
import re
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
TARGET = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
BLESS = os.environ.get("DOCS_BLESS") == "1"
PAGES = [ROOT / "README.md"] + sorted((ROOT / "docs" / "src").rglob("*.md"))

# Examples that are not run, by a text they contain, and why.
NOT_RUN = {
    "$ tests/run": "the test command itself, which runs this file",
    "$ pip install": "tests/run installs the package from ./python exactly so before these tests",
    "SLURMCluster": "needs a Slurm cluster",
    "--param speed=1:50:0.01": "4,901 points and an interruption by Ctrl-C: the resume tests (runner/cli/tests/resume.rs) run it smaller",
    "UPDATE_CATALOGUE=1": "rewrites MODELS.md; tests/run's cargo test runs the same tests without it",
    "$ tests/bench/run": "the benchmarks take minutes and are not part of CI",
    "(Ctrl-C to stop)": "runner serve runs until Ctrl-C: tests/serve starts it on a free port and checks its API and page",
}

FENCE = re.compile(r"^```(\S*)\s*$")


def blocks(page):
    """The fenced blocks of `page`: (line number, info string, text)."""
    found, info, start, lines = [], None, 0, []
    for n, line in enumerate(page.read_text().splitlines(), 1):
        m = FENCE.match(line.strip())
        if info is None and m:
            info, start, lines = m.group(1), n, []
        elif info is not None and line.strip() == "```":
            found.append((start, info, "\n".join(lines)))
            info = None
        elif info is not None:
            # Blocks inside list items are indented; keep the text relative to the fence.
            lines.append(line)
    return found


def dedent(text):
    lines = text.splitlines()
    indent = min((len(l) - len(l.lstrip()) for l in lines if l.strip()), default=0)
    return [l[indent:] for l in lines]


def commands(text):
    """A console block's commands: (command, expected output lines, exit code, the command's
    lines as written)."""
    out, current = [], None
    lines = iter(dedent(text))
    for line in lines:
        if line.startswith("$ "):
            cmd, raw = line[2:], [line]
            while cmd.endswith("\\"):
                raw.append(next(lines))
                cmd = cmd[:-1] + " " + raw[-1].strip()
            current = [cmd, [], 0, raw]
            out.append(current)
        elif current is None:
            raise AssertionError(f"output before the first command: {line!r}")
        elif re.fullmatch(r"\? \d+", line.strip()):
            current[2] = int(line.strip()[2:])
        else:
            current[1].append(line.rstrip())
    return out


def matches(expected, actual):
    """Whether `actual` lines match `expected` lines with `...` lines and `[..]` wildcards."""
    if not expected:
        return not actual
    if expected[0] == "...":
        return any(matches(expected[1:], actual[k:]) for k in range(len(actual) + 1))
    if not actual:
        return False
    pattern = ".*".join(re.escape(part) for part in expected[0].split("[..]"))
    return re.fullmatch(pattern, actual[0]) is not None and matches(expected[1:], actual[1:])


def skipped(text):
    return [reason for key, reason in NOT_RUN.items() if key in text]


def examples():
    cases = []
    for page in PAGES:
        runnable = [(n, info, text) for n, info, text in blocks(page)
                    if info.split(",")[0] in ("console", "python", "sh", "bash", "shell")]
        if runnable:
            cases.append(pytest.param(page, runnable, id=str(page.relative_to(ROOT))))
    return cases


@pytest.fixture(scope="module")
def environment():
    venv = pathlib.Path(sys.executable).parent
    path = f"{TARGET / 'release'}{os.pathsep}{venv}{os.pathsep}{os.environ['PATH']}"
    runner = TARGET / "release" / "runner"
    assert runner.is_file(), f"{runner} is missing: build it first (cargo build --release -p runner)"
    return dict(os.environ, PATH=path, CARGO_TARGET_DIR=str(TARGET), COLUMNS="100", NO_COLOR="1")


@pytest.mark.parametrize("page,runnable", examples())
def test_examples_run_as_written(page, runnable, environment, tmp_path):
    scratch = tmp_path / "work"
    scratch.mkdir()
    (scratch / "target").symlink_to(TARGET)
    (scratch / "systems").symlink_to(ROOT / "systems")
    shared = ROOT.parent / "shared"
    if shared.is_dir():
        (tmp_path / "shared").symlink_to(shared)
    where = page.relative_to(ROOT)
    blessed, failures = {}, []
    for line, info, text in runnable:
        if skipped(text) or ("../shared/reference-fmus" in text and not (shared / "reference-fmus").is_dir()):
            continue
        kind = info.split(",")[0]
        if kind in ("sh", "bash", "shell"):
            pytest.fail(f"{where}:{line}: a ```{kind} block; write command examples as ```console blocks so they run")
        if kind == "python":
            script = scratch / f"example_{line}.py"
            script.write_text(text)
            done = subprocess.run([sys.executable, script.name], cwd=scratch, env=environment, capture_output=True, text=True,
                                  stdin=subprocess.DEVNULL, timeout=600)
            if BLESS and done.returncode != 0:
                failures.append(f"{where}:{line}: the Python example failed:\n{done.stdout}{done.stderr}")
                continue
            assert done.returncode == 0, f"{where}:{line}: the Python example failed:\n{done.stdout}{done.stderr}"
            continue
        new = []
        for cmd, expected, code, raw in commands(text):
            run = re.sub(r"^cargo run --release -p runner -- ", "runner ", cmd)
            done = subprocess.run(["bash", "-c", run], cwd=scratch, env=environment, stdout=subprocess.PIPE,
                                  stderr=subprocess.STDOUT, text=True, stdin=subprocess.DEVNULL, timeout=600)
            actual = [l.rstrip() for l in done.stdout.splitlines()]
            if BLESS:
                keep = matches(expected, actual) and done.returncode == code
                new.append((raw, expected if keep else actual, done.returncode))
                continue
            assert done.returncode == code, f"{where}:{line}: `{cmd}` exited with {done.returncode}, not {code}:\n{done.stdout}"
            assert matches(expected, actual), (f"{where}:{line}: `{cmd}` printed\n" + "\n".join(actual)
                                               + "\n--- where the page shows\n" + "\n".join(expected))
        if BLESS:
            blessed[line] = new
    if blessed:
        rewrite(page, blessed)
    assert not failures, "\n".join(failures)


def rewrite(page, blessed):
    """DOCS_BLESS: the console blocks starting at the given lines get the actual outputs."""
    lines = page.read_text().split("\n")
    for start in sorted(blessed, reverse=True):
        end = next(k for k in range(start, len(lines)) if lines[k].strip() == "```")
        indent = lines[start - 1][: len(lines[start - 1]) - len(lines[start - 1].lstrip())]
        body = []
        for raw, output, code in blessed[start]:
            body.extend(indent + l for l in raw)
            body.extend(indent + l if l else l for l in output)
            if code:
                body.append(f"{indent}? {code}")
        lines[start:end] = body
    page.write_text("\n".join(lines))


def test_every_not_run_entry_names_an_example():
    """An entry of NOT_RUN that matches no example any more is stale."""
    texts = [text for page in PAGES for _, _, text in blocks(page)]
    for key in NOT_RUN:
        assert any(key in t for t in texts), f"NOT_RUN entry {key!r} matches no example"


def test_the_matcher():
    assert matches(["a", "...", "d"], ["a", "b", "c", "d"])
    assert matches(["a", "...", "b"], ["a", "b"])
    assert not matches(["a", "b"], ["a", "b", "c"])
    assert matches(["x = [..] s"], ["x = 12.5 s"])
    assert not matches(["x = [..] s"], ["x = 12.5 m"])
    assert commands("$ echo a \\\n  b\na b\n? 1") == [["echo a  b", ["a b"], 1, ["$ echo a \\", "  b"]]]
