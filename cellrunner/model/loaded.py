"""A cell file and a task file as loaded and checked (:class:`LoadedCell`,
:class:`LoadedTask`, each task step as a :class:`StepSpec`): what every command works
from. :mod:`cellrunner.model.load` makes them."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cellrunner.errors import Diagnostic
from cellrunner.model.cell import Cell, Tool
from cellrunner.model.robots import RobotSpec, robot_spec
from cellrunner.model.source import PathKey, Source
from cellrunner.model.step_kinds import kind_of
from cellrunner.model.task import TaskFile

if TYPE_CHECKING:
    from cellrunner.model.geometry import Placed
    from cellrunner.model.params import Param


@dataclass
class LoadedCell:
    cell: Cell
    path: Path
    source: Source
    warnings: list[Diagnostic]
    #: the cell file's and every mesh file's SHA-256 together (hex), taken on loading: a
    #: plan is keyed by it (planning.job_plan), so no file is read again per job
    digest: str = ""

    @property
    def folder(self) -> Path:
        return self.path.parent

    @property
    def spec(self) -> RobotSpec:
        """The arm with the cell's ``robot.joint_range`` applied (checked on loading)."""
        return robot_spec(self.cell.robot.model).narrowed(self.cell.robot.joint_range)

    @property
    def root(self) -> Path:
        """The project folder: the parent of ``cells/`` when the cell file lives in one."""
        folder = self.path.resolve().parent
        return folder.parent if folder.name == "cells" else folder

    def tool_shapes(self, tool: Tool | None = None) -> list[Placed]:
        """The declared geometry of ``tool`` (default: the mounted one) as placed shapes in
        the flange frame."""
        from cellrunner.model.geometry import Placed

        geometry = (tool or self.cell.tool).geometry
        return [
            Placed(
                f"tool{i}" if len(geometry) > 1 else "gripper", g.to_shape(self.resolve), g.matrix()
            )
            for i, g in enumerate(geometry)
        ]

    def fixture_shapes(self) -> list[Placed]:
        """The fixtures as placed shapes in the world."""
        from cellrunner.model.geometry import Placed

        return [Placed(f.name, f.to_shape(self.resolve), f.matrix()) for f in self.cell.fixtures]

    def resolve(self, relative: str) -> Path:
        """A path written in the cell file. Relative paths are looked up against the
        project root, then the cell file's folder, then the working directory; the first
        that exists wins, else the one under the project root (for files to create)."""
        p = Path(relative)
        if p.is_absolute():
            return p
        for base in (self.root, self.path.resolve().parent, Path.cwd()):
            if (base / p).exists():
                return base / p
        return self.root / p

    def resolve_output(self, relative: str) -> Path:
        """A file cellrunner writes (the journal, the PKI folder): relative paths are the
        project root's, or the cell file folder's where one already exists there; never
        the working directory's, so that a cell served from another folder does not take
        over that folder's journal."""
        p = Path(relative)
        if p.is_absolute():
            return p
        beside = self.path.resolve().parent / p
        return beside if not (self.root / p).exists() and beside.exists() else self.root / p


@dataclass
class StepSpec:
    """One step as written in a task file, validated: kind, argument model, file path."""

    kind: str
    args: Any
    path: PathKey
    between: list[StepSpec] = field(default_factory=list)  # pick retry.between steps
    raw: Any = None  # the widened arguments as written, when they name float params
    refs: frozenset[str] = frozenset()  # the float params they name

    def bind(self, params: dict[str, Param], values: dict[str, Any]) -> Any:
        """The arguments with the named params' values (``args`` when none are named)."""
        if not self.refs:
            return self.args
        from cellrunner.model.params import substitute

        model = kind_of(self.kind).args
        assert model is not None  # a kind a file wrote
        return model.model_validate(substitute(self.raw, params, values)[0])


@dataclass
class LoadedTask:
    task: TaskFile
    path: Path
    source: Source
    steps: list[StepSpec]
    warnings: list[Diagnostic]
    on_error: list[StepSpec] = field(default_factory=list)

    @property
    def name(self) -> str:
        return self.task.task
