"""Step kinds: each kind of task step is one module of :mod:`cellrunner.steps` holding one
:class:`StepKindDef` subclass, registered once with :func:`register`.

A kind's module says everything about it: the model of its arguments and their short
form, its schema help, how it expands into primitive steps and resolves its target, which
references it checks against the cell, how ``check`` plans it, how a job runs it, and the
colour of its bar in a report. Every layer asks :data:`STEP_KINDS` instead of keeping a
table of its own (see docs/adding-a-step.md).

The registry sits in the model layer and finds the kinds' modules when it is first
asked (the modules of :mod:`cellrunner.steps`, imported by name): a kind's module may use
planning and execution, which the model layer itself never imports. The hooks receive the
context they work in (the expansion, the reference check, the planner, the job's
context), typed where each is written.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING, Any, ClassVar, Literal, TypeVar

from cellrunner.errors import StepKindError

if TYPE_CHECKING:
    import numpy as np

    from cellrunner.model.base import Strict

#: how a motion kind moves: a collision-free planned joint move, a straight TCP line, or a
#: straight line stopped by the wrist force
Motion = Literal["planned", "line", "guarded"]

#: the package whose modules are the step kinds
STEPS_PACKAGE = "cellrunner.steps"


class StepKindDef:
    """One kind of step. Subclass it in ``cellrunner/steps/<kind>.py`` and decorate the
    subclass with :func:`register`; the defaults fit a primitive that does not move."""

    #: the key a task file writes (``{name: ARGS}``)
    name: ClassVar[str]
    #: where it stands in lists of the kinds (messages, the schema): motions first
    order: ClassVar[int] = 100
    #: the model of its arguments; None: a primitive that only an expansion makes
    args: ClassVar[type[Strict] | None] = None
    #: what it does, for the schema's hover text
    summary: ClassVar[str] = ""
    #: an example of its arguments (completion in an editor)
    example: ClassVar[Any] = None
    #: the argument a short form (``lift: 0.1``) fills, and the JSON type it is checked as
    short_field: ClassVar[str | None] = None
    short_schema: ClassVar[Any] = None
    #: the Python types a short form may have (None: anything that is not a mapping)
    short_types: ClassVar[tuple[type, ...] | None] = None
    #: may be written bare, without arguments (``- release``)
    bare: ClassVar[bool] = False
    #: expands into several primitives (pick, place, change_tool)
    macro: ClassVar[bool] = False
    #: only a task's own steps may hold it (not on_error, not a retry's between)
    top_level_only: ClassVar[bool] = False
    #: how it moves the arm; None: it does not
    motion: ClassVar[Motion | None] = None
    #: the colour of its bar in a report's steps lane
    colour: ClassVar[str] = "#dddddd"

    @property
    def written(self) -> bool:
        """A task file may write it."""
        return self.args is not None

    def widen(self, value: Any) -> Any:
        """The full mapping form of arguments written in short form."""
        if value is None:
            return {}
        if self.short_field is None or isinstance(value, dict):
            return value
        if self.short_types is not None and not isinstance(value, self.short_types):
            return value
        return {self.short_field: value}

    # -- expansion (model.expand) ---------------------------------------------------

    def expand(self, builder: Any, spec: Any, args: Any) -> None:
        """Append this step's primitives to ``builder`` (a primitive: itself)."""
        builder.steps.append(builder.primitive(self.name, args, spec.path, builder.next_index()))

    def target(self, builder: Any, args: Any) -> tuple[str, np.ndarray | None, Any]:
        """(name, T_world_tcp goal, joint goal in deg) of a primitive with ``args``."""
        return self.name, None, None

    def target_frame(self, args: Any) -> str | None:
        """The cell frame its target is aimed at (an align before it corrects it)."""
        return None

    # -- references (model.references) -----------------------------------------------

    def check_references(self, refs: Any, spec: Any) -> None:
        """Report the names ``spec`` uses that its cell lacks."""

    # -- planning (planning.task_plan) -------------------------------------------------

    def plan(self, planner: Any, row: Any) -> None:
        """Plan a step that does not move: its duration, what it changes in the planner's
        state (the part held, the tool mounted), and why it cannot be done."""

    def line_goal(self, planner: Any, step: Any, T_now: np.ndarray) -> np.ndarray:
        """T_world_tcp where a straight line of this kind ends, from ``T_now``."""
        assert step.T_world_tcp is not None  # a line with a frame target
        goal: np.ndarray = step.T_world_tcp
        return goal

    def check_line(self, planner: Any, step: Any, path: np.ndarray) -> None:
        """Refuse a planned straight line of this kind (joint samples ``path``) that cannot
        do what the step is for."""

    # -- running (execution.dispatch) ---------------------------------------------------

    def run(self, ctx: Any, step: Any, resume: bool) -> Any:
        """The generator that runs ``step`` in a job, one tick per ``next``."""
        raise StepKindError(f"step kind {self.name!r} has no run-time behaviour")


_K = TypeVar("_K", bound=type[StepKindDef])


class StepKinds(Mapping[str, StepKindDef]):
    """Every step kind by name, found in :data:`STEPS_PACKAGE` on first use; a second
    kind of one name is refused, and an unknown name is answered with the known ones."""

    def __init__(self, package: str) -> None:
        self._package = package
        self._kinds: dict[str, StepKindDef] = {}
        self._loaded = False

    def register(self, cls: _K) -> _K:
        """Class decorator: add one instance of ``cls`` under ``cls.name``."""
        name = getattr(cls, "name", None)
        if not isinstance(name, str) or not name:
            raise StepKindError(f"step kind {cls.__qualname__} has no name")
        known = self._kinds.get(name)
        if known is not None and type(known).__qualname__ != cls.__qualname__:
            raise StepKindError(
                f"step kind {name!r} is registered twice: by {type(known).__module__} "
                f"and by {cls.__module__}"
            )
        self._kinds[name] = cls()
        return cls

    def _load(self) -> None:
        if self._loaded:
            return
        self._loaded = True  # a kind's module that asks for a kind as it loads finds it
        try:
            package = importlib.import_module(self._package)
            for module in sorted(m.name for m in pkgutil.iter_modules(package.__path__)):
                if not module.startswith("_"):
                    importlib.import_module(f"{self._package}.{module}")
        except BaseException:
            self._loaded = False
            raise
        ordered = sorted(self._kinds.items(), key=lambda item: (item[1].order, item[0]))
        self._kinds = dict(ordered)

    def __getitem__(self, name: str) -> StepKindDef:
        self._load()
        kind = self._kinds.get(name)
        if kind is None:
            raise StepKindError(f"unknown step kind {name!r}; known: {', '.join(self)}")
        return kind

    def get(self, name: str, default: StepKindDef | None = None) -> StepKindDef | None:  # type: ignore[override]
        self._load()
        return self._kinds.get(name, default)

    def __iter__(self) -> Iterator[str]:
        self._load()
        return iter(self._kinds)

    def __len__(self) -> int:
        self._load()
        return len(self._kinds)

    def written(self) -> list[str]:
        """The kinds a task file may write, in the registry's order."""
        return [name for name, kind in self.items() if kind.written]


#: the step kinds (the modules of :mod:`cellrunner.steps`)
STEP_KINDS = StepKinds(STEPS_PACKAGE)
register = STEP_KINDS.register


def kind_of(name: str) -> StepKindDef:
    """The definition of step kind ``name`` (StepKindError, naming the known, if none)."""
    return STEP_KINDS[name]
