"""MODELS.md, the public variable catalogue: one generated entry per model crate (each model's
Rust test `catalogue_entry_is_current` checks its entry against its variable table), and each
entry lists the variables the built FMU declares, in order, up to the solver controls the
toolkit appends to every FMU alike (described once in MODELS.md)."""

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
        tails.add(tuple(declared[len(listed):]))
    # What follows the model's own variables is the same in every FMU: the solver controls.
    assert len(tails) == 1 and "solver" in next(iter(tails)), tails
