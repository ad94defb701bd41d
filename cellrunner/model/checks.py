"""Checks shared by the cell file, the task file and the ``sim:`` rules: IO names and
angles that look like radians."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from cellrunner.model.diagnose import known_list, unknown_name
from cellrunner.model.source import PathKey
from cellrunner.model.units import looks_like_radians

if TYPE_CHECKING:
    from cellrunner.model.cell import Cell
    from cellrunner.model.report import Report


def check_io_name(
    cell: Cell, name: str, side: str, path: PathKey, report: Report, at_key: bool = False
) -> None:
    """Report ``name`` unless it is a known IO of ``side`` ('inputs' or 'outputs')."""
    table = getattr(cell.io, side)
    if name in table:
        return
    other = "outputs" if side == "inputs" else "inputs"
    if name in getattr(cell.io, other):
        report.error(
            path,
            f"{name!r} is an {other[:-1]}, not an {side[:-1]}; known {side}: {known_list(table)}",
            at_key=at_key,
        )
    else:
        report.error(path, unknown_name(side[:-1], name, table), at_key=at_key)


def check_radians(raw: Any, path: PathKey, report: Report) -> None:
    """Warn when the number list at ``path`` of ``raw`` looks like radians."""
    value = raw
    for part in path:
        if not isinstance(value, (dict, list)):
            return
        try:
            value = value[part]
        except (KeyError, IndexError, TypeError):
            return
    if (
        isinstance(value, list)
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
        and looks_like_radians([float(v) for v in value])
    ):
        report.warn(
            path,
            f"{value} looks like radians; angles are in degrees "
            "(write e.g. '1.57 rad' if you mean radians)",
        )


def check_sim_block(cell: Cell, report: Report) -> None:
    """Report rule inputs, outputs and frames the cell does not know."""
    if cell.sim is None:
        return
    feed = cell.sim.feed
    if feed is not None:
        parts = [p.name for p in cell.parts]
        if feed.part not in parts:
            report.error(("sim", "feed", "part"), unknown_name("part", feed.part, parts))
        if feed.at is not None and feed.at not in cell.frames:
            report.error(("sim", "feed", "at"), unknown_name("frame", feed.at, cell.frames))
        if feed.conveyor is not None and feed.conveyor not in cell.conveyors:
            report.error(
                ("sim", "feed", "conveyor"), unknown_name("conveyor", feed.conveyor, cell.conveyors)
            )
    names = [i.name for i in cell.sim.intruders]
    for i, intruder in enumerate(cell.sim.intruders):
        if names.index(intruder.name) != i:
            report.error(
                ("sim", "intruders", i, "name"), f"intruder {intruder.name!r} is listed twice"
            )
        if intruder.at is not None and intruder.at not in cell.frames:
            report.error(
                ("sim", "intruders", i, "at"), unknown_name("frame", intruder.at, cell.frames)
            )
    for name, rule in cell.sim.inputs.items():
        base = ("sim", "inputs", name)
        check_io_name(cell, name, "inputs", base, report, at_key=True)
        if rule.part_at is not None and rule.part_at not in cell.frames:
            report.error(base + ("part_at",), unknown_name("frame", rule.part_at, cell.frames))
        for key in ("follows", "pulse_after"):
            output = getattr(rule, key)
            if output is not None:
                check_io_name(cell, output, "outputs", base + (key,), report)


def check_watch(cell: Cell, report: Report) -> None:
    """Every watched camera exists and is a depth camera; names appear once."""
    watch = cell.watch
    if watch is None:
        return
    seen: set[str] = set()
    for i, name in enumerate(watch.cameras):
        where = ("watch", "cameras", i)
        if name in seen:
            report.error(where, f"camera {name!r} is listed twice")
        seen.add(name)
        camera = cell.cameras.get(name)
        if camera is None:
            report.error(where, unknown_name("camera", name, cell.cameras))
        elif camera.depth is None:
            depth = [n for n, c in cell.cameras.items() if c.depth is not None]
            report.error(
                where,
                f"camera {name!r} has no 'depth:'; depth cameras: {', '.join(depth) or '(none)'}",
            )
