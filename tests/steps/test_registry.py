"""The step kinds' registry: one module per kind, found by the registry, each kind once;
and a kind added as one module works end to end (load, references, expansion, schema,
check) with no other file touched."""

from __future__ import annotations

import inspect
import sys
import textwrap
from pathlib import Path
from typing import Any, ClassVar

import pytest

from cellrunner.errors import StepKindError
from cellrunner.model.base import Name, Strict
from cellrunner.model.expand import expand, resolve_params
from cellrunner.model.load import load_cell, load_task
from cellrunner.model.schema import task_schema
from cellrunner.model.step_kinds import STEP_KINDS, StepKindDef, StepKinds
from cellrunner.model.units import PositiveDuration
from tests.cells.spec_written_rig import cli
from tests.conftest import DEMO_CELL


def _package(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, modules: dict[str, str]) -> str:
    root = tmp_path / "kinds_pkg"
    root.mkdir()
    (root / "__init__.py").write_text("")
    for name, body in modules.items():
        (root / f"{name}.py").write_text(textwrap.dedent(body))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(sys, "dont_write_bytecode", True)
    return "kinds_pkg"


_KIND = """
from cellrunner.model.step_kinds import StepKindDef
import kinds_pkg._registry as r

@r.KINDS.register
class {cls}(StepKindDef):
    name = "{name}"
    order = {order}
"""


def test_the_registry_finds_each_module_of_its_package_in_order(tmp_path, monkeypatch):
    package = _package(
        tmp_path,
        monkeypatch,
        {
            "_registry": "from cellrunner.model.step_kinds import StepKinds\nKINDS = StepKinds('kinds_pkg')\n",
            "zeta": _KIND.format(cls="Zeta", name="zeta", order=0),
            "alpha": _KIND.format(cls="Alpha", name="alpha", order=5),
        },
    )
    import importlib

    kinds = importlib.import_module(f"{package}._registry").KINDS
    assert list(kinds) == ["zeta", "alpha"]  # by order, then name; _registry is no kind
    with pytest.raises(StepKindError, match=r"unknown step kind 'beta'; known: zeta, alpha"):
        kinds["beta"]
    assert kinds.get("beta") is None


def test_a_second_kind_of_one_name_is_refused_naming_both_modules():
    kinds = StepKinds("cellrunner.steps")

    class One(StepKindDef):
        name = "twice"

    class Other(StepKindDef):
        name = "twice"

    kinds.register(One)
    with pytest.raises(StepKindError, match=r"'twice' is registered twice: by .* and by "):
        kinds.register(Other)

    class Nameless(StepKindDef):
        pass

    with pytest.raises(StepKindError, match="has no name"):
        kinds.register(Nameless)


def test_every_kind_has_a_behaviour_and_every_written_kind_its_help():
    assert len(STEP_KINDS) >= 19
    for name, kind in STEP_KINDS.items():
        if not kind.macro:  # a macro runs as the primitives it expands into
            assert inspect.isgenerator(kind.run(None, None, False)), name  # built, not started
        if kind.written:
            assert kind.summary and kind.example is not None, name


class BeepArgs(Strict):
    output: Name
    """The output the beep sets. Example: `beacon`"""
    seconds: PositiveDuration = 0.2
    """How long it sounds, s. Example: `0.2`"""


class Beep(StepKindDef):
    """A kind as a new module would write it: a pulse on an output."""

    name = "beep"
    args = BeepArgs
    summary = "Sound a beacon for a moment."
    example: ClassVar[Any] = {"output": "beacon"}
    short_field = "output"
    short_types = (str,)
    short_schema = str
    colour = "#ff0000"

    def target(self, builder: Any, args: Any) -> tuple[str, None, None]:
        return f"{args.output} {args.seconds:g} s", None, None

    def check_references(self, refs: Any, spec: Any) -> None:
        refs.output(spec.args.output, spec.path + ("output",))

    def plan(self, planner: Any, row: Any) -> None:
        row.duration_s = row.step.args.seconds


@pytest.fixture
def beep(monkeypatch):
    list(STEP_KINDS)  # every built-in kind found first
    monkeypatch.setitem(STEP_KINDS._kinds, "beep", Beep())
    return Beep


def _task(tmp_path: Path, step: str) -> Path:
    path = tmp_path / "beep.yaml"
    path.write_text(f"task: beep\nsteps:\n  - move: home\n  - {step}\n  - move: home\n")
    return path


def test_a_new_kind_module_is_loaded_checked_expanded_and_planned(tmp_path, beep):
    cell = load_cell(DEMO_CELL)
    loaded = load_task(_task(tmp_path, "beep: beacon"), cell)
    steps = expand(loaded, cell.cell, resolve_params(loaded.task, {}))
    assert [(s.kind, s.name) for s in steps] == [
        ("move", "home"),
        ("beep", "beacon 0.2 s"),
        ("move", "home"),
    ]
    assert "beep" in task_schema()["properties"]["steps"]["items"]["else"]["properties"]
    code, out = cli("check", str(DEMO_CELL), str(_task(tmp_path, "beep: {output: beacon}")))
    assert code == 0, out
    row = next(r for r in out["steps"] if r["kind"] == "beep")
    assert row["status"] == "ok" and row["duration_s"] == pytest.approx(0.2)


def test_a_new_kind_s_references_are_checked_and_located(tmp_path, beep):
    code, out = cli("check", str(DEMO_CELL), str(_task(tmp_path, "beep: {output: beakon}")))
    assert code == 2
    assert any("beep.yaml:4:12:" in e and "'beakon'" in e for e in out["errors"]), out
