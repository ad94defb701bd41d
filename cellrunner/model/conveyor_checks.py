"""Checks of a cell's ``conveyors:`` against the rest of the cell file: frames, the
photo-eye's input, where the eye and the window lie on the path, PLC registers."""

from __future__ import annotations

from typing import TYPE_CHECKING

from cellrunner.model.checks import check_io_name
from cellrunner.model.conveyor import FRAME_ON_PATH_M, s_of_point_m
from cellrunner.model.diagnose import unknown_name
from cellrunner.model.rotation import rpy_rows

if TYPE_CHECKING:
    from cellrunner.model.cell import Cell
    from cellrunner.model.report import Report


def check_conveyors(cell: Cell, report: Report) -> None:
    """Each conveyor's frame and trigger input exist, its frame lies on its path, its
    eye and window lie on the path, and no two PLC encoders share registers."""
    registers: dict[int, str] = {}
    for name, conveyor in cell.conveyors.items():
        base = ("conveyors", name)
        check_io_name(cell, conveyor.trigger.input, "inputs", base + ("trigger", "input"), report)
        encoder = conveyor.encoder
        if encoder.register_ is not None:
            if encoder.register_ in registers:
                report.error(
                    base + ("encoder", "register"),
                    f"registers {encoder.register_}-{encoder.register_ + 1} already carry "
                    f"conveyor {registers[encoder.register_]!r}'s encoder",
                )
            registers[encoder.register_] = name
        if conveyor.frame not in cell.frames:
            report.error(base + ("frame",), unknown_name("frame", conveyor.frame, cell.frames))
            continue
        p = frame_origin_m(cell, conveyor.frame)
        if p is None:  # a loop of parents: reported with the frames
            continue
        s_frame, off = s_of_point_m(conveyor.path, p)
        length = conveyor.path.length_m
        if off > FRAME_ON_PATH_M:
            report.error(
                base + ("frame",),
                f"frame {conveyor.frame!r} lies {off * 1000:.0f} mm off the conveyor's path "
                f"(at most {FRAME_ON_PATH_M * 1000:.0f} mm): a part on the belt never reaches it",
            )
            continue
        s_eye = s_frame - conveyor.eye_to_frame
        if not 0.0 <= s_eye <= length:
            report.error(
                base + ("eye_to_frame",),
                f"the eye {conveyor.eye_to_frame:g} m before {conveyor.frame!r} lies at "
                f"{s_eye:.3f} m along a path of {length:.3f} m",
            )
        lo, hi = conveyor.window
        if s_frame + lo < -1e-9 or s_frame + hi > length + 1e-9:
            report.error(
                base + ("window",),
                f"window [{lo:g}, {hi:g}] m about {conveyor.frame!r} (at {s_frame:.3f} m) runs "
                f"off the path [0, {length:.3f}] m; it may run [{-s_frame:.3f}, "
                f"{length - s_frame:.3f}]",
            )


def frame_origin_m(cell: Cell, name: str) -> list[float] | None:
    """Where frame ``name``'s origin lies in the world, m (None when its parents loop),
    in plain Python: ``validate`` never imports numpy."""
    p = [0.0, 0.0, 0.0]
    seen: set[str] = set()
    while name != "world":
        if name in seen or name not in cell.frames:
            return None
        seen.add(name)
        frame = cell.frames[name]
        R = rpy_rows(frame.rpy)
        p = [sum(R[i][k] * p[k] for k in range(3)) + float(frame.xyz[i]) for i in range(3)]
        name = frame.parent
    return p
