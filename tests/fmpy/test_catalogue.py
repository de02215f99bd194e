"""MODELS.md, the public variable catalogue: one generated entry per model crate (each model's
Rust test `catalogue_entry_is_current` checks its entry against its variable table), and each
entry lists the variables the built FMU declares, in order, up to what the toolkit appends to
every FMU alike (described once in MODELS.md): the solver controls, `time`, and `der(x)` for
each state x."""

import re

from fmpy import read_model_description

from conftest import MODELS, ROOT, fmu_path

def _entries():
    text = (ROOT / "MODELS.md").read_text()
    return dict(re.findall(r"(?ms)^<!-- catalogue (\w+):.*?-->\n(.*?)^<!-- end of catalogue \1 -->", text))


def test_every_model_has_one_entry_and_every_entry_is_a_model():
    text = (ROOT / "MODELS.md").read_text()
    ids = re.findall(r"(?m)^<!-- catalogue (\w+):", text)
    assert sorted(ids) == MODELS, "run `UPDATE_CATALOGUE=1 cargo test --workspace catalogue`"
    assert len(ids) == len(set(ids))


def test_each_entry_lists_the_variables_of_the_built_fmu():
    entries = _entries()
    tails = set()
    for model in MODELS:
        listed = re.findall(r"(?m)^\| `(\w+)` \|", entries[model])
        declared = [v.name for v in read_model_description(str(fmu_path(model))).modelVariables]
        assert listed and declared[: len(listed)] == listed, model
        tail = declared[len(listed):]
        # The state derivatives, named after the states (which the entry lists), come last.
        derivatives = [name for name in tail if name.startswith("der(")]
        assert tail[len(tail) - len(derivatives):] == derivatives, model
        assert all(d[4:-1] in listed for d in derivatives), (model, derivatives)
        tails.add(tuple(tail[: len(tail) - len(derivatives)]))
    # What follows the model's own variables is the same in every FMU: the solver controls
    # and time (max_step came last among the controls, after the counters, so that the older value
    # references stay as they were).
    assert tails == {("solver", "fixed_step", "abs_tol", "n_steps", "n_rhs", "max_step", "time")}, tails
