"""``move``: a planned, collision-free joint move to a frame, ``home`` or joint angles."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

from cellrunner.model.checks import check_radians
from cellrunner.model.diagnose import unknown_name
from cellrunner.model.step_kinds import Motion, register
from cellrunner.model.task import MoveArgs, Target
from cellrunner.steps._families import MotionKind

if TYPE_CHECKING:
    import numpy as np

    from cellrunner.model.expand import Expansion
    from cellrunner.model.references import ReferenceCheck


@register
class Move(MotionKind):
    name = "move"
    order = 0
    args = MoveArgs
    motion: ClassVar[Motion | None] = "planned"
    summary = (
        "Planned, collision-free joint move to a frame, 'home' or six joint angles (deg); "
        "or {to, offset, speed (fraction of the limits)}."
    )
    example = "home"
    short_field = "to"
    short_schema = Target
    colour = "#8da0cb"

    def target(self, builder: Expansion, args: Any) -> tuple[str, np.ndarray | None, Any]:
        if isinstance(args.to, list):
            return "joints", None, tuple(args.to)
        if args.to == "home":
            return "home", None, tuple(builder.cell.robot.home)
        T, name = builder.target(args.to, args.offset, args.pattern)
        return name, T, None

    def target_frame(self, args: Any) -> str | None:
        return args.to if isinstance(args.to, str) and args.to != "home" else None

    def check_references(self, refs: ReferenceCheck, spec: Any) -> None:
        to, path = spec.args.to, spec.path
        if isinstance(to, str) and to != "home" and to not in refs.cell.frames:
            refs.report.error(path + ("to",), unknown_name("target", to, ["home", *refs.frames]))
        if isinstance(to, list):
            raw_path = path if refs.is_short(path) else path + ("to",)
            check_radians(refs.report.source.data, raw_path, refs.report)
