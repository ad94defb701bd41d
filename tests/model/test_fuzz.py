"""Mutating the example files never makes the loader raise anything but InputError."""

from __future__ import annotations

import copy
import io
import tempfile
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from ruamel.yaml import YAML

from cellrunner.errors import InputError
from cellrunner.model.expand import expand, resolve_params
from cellrunner.model.load import load_cell, load_task
from tests.conftest import DEMO_CELL, PICK_PLACE

yaml = YAML(typ="safe", pure=True)
CELL = yaml.load(DEMO_CELL.read_text())
TASK = yaml.load(PICK_PLACE.read_text())

values = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**6), 10**6),
    st.floats(allow_nan=True),
    st.text(max_size=12),
    st.sampled_from(["500 mm", "1 rad", "ur5e", "infeed", "DO0", "home", "-1", ""]),
    st.lists(st.integers(-400, 400), max_size=7),
    st.dictionaries(st.text(max_size=5), st.integers(), max_size=2),
)


def _paths(node, prefix=()):
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _paths(v, prefix + (i,))


def _mutate(doc, data):
    doc = copy.deepcopy(doc)
    paths = list(_paths(doc))[1:]
    for _ in range(data.draw(st.integers(1, 3))):
        path = data.draw(st.sampled_from(paths))
        parent = doc
        try:
            for part in path[:-1]:
                parent = parent[part]
            action = data.draw(st.sampled_from(["replace", "delete", "add"]))
            if action == "replace":
                parent[path[-1]] = data.draw(values)
            elif action == "delete" and isinstance(parent, dict):
                del parent[path[-1]]
            elif isinstance(parent, dict):
                parent[data.draw(st.text(max_size=6))] = data.draw(values)
        except (KeyError, IndexError, TypeError):
            pass
    return doc


def _dump(doc) -> str:
    out = io.StringIO()
    YAML(typ="safe", pure=True).dump(doc, out)
    return out.getvalue()


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_mutated_cells_and_tasks_only_raise_input_error(data):
    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        (folder / "tasks").mkdir()
        (folder / "tasks" / "pick_place.yaml").write_text(_dump(_mutate(TASK, data)))
        (folder / "tasks" / "home.yaml").write_text("task: home\nsteps: [release, {move: home}]\n")
        cell_text = _dump(_mutate(CELL, data))
        if data.draw(st.booleans()):  # also raw text damage
            i = data.draw(st.integers(0, max(0, len(cell_text) - 1)))
            cell_text = (
                cell_text[:i]
                + data.draw(st.sampled_from(["", ":", "- ", "{", "\t", "]"]))
                + cell_text[i + 1 :]
            )
        (folder / "cell.yaml").write_text(cell_text)
        try:
            cell = load_cell(folder / "cell.yaml")
            task = load_task(folder / "tasks" / "pick_place.yaml", cell)
            expand(task, cell.cell, resolve_params(task.task, {}))
        except InputError as exc:
            assert exc.diagnostics
            for d in exc.diagnostics:
                assert d.line >= 1 and d.col >= 1 and d.message
