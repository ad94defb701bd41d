"""``change_tool: NAME`` expanded into primitive steps (SPEC section 11).

From tool A to tool B, with the rack frames ``rack[A]``, ``rack[B]`` (each the TCP pose of
that tool parked in the rack):

    approach rack[A] -> descend rack[A] -> tool_unlock (A stays in the rack) -> retreat
    -> approach rack[B] -> descend rack[B] -> tool_lock (B mounted) -> retreat

Between the unlock and the lock the flange carries no tool; those moves are planned with
A's TCP as a virtual point (no geometry, no payload), so rack[B] is converted to the pose
A's TCP has when B's TCP is at rack[B]. Each step's ``extra['tool']`` names the tool the
step is planned and run with (None: the bare flange).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from cellrunner.model import geometry
from cellrunner.model.frames import frame_pose
from cellrunner.model.step import Macro, Step, StepKind
from cellrunner.model.task import ApproachArgs, DistanceArgs, GripArgs, LinearArgs

if TYPE_CHECKING:
    from cellrunner.model.cell import Cell
    from cellrunner.model.loaded import StepSpec


def expand_change_tool(
    cell: Cell, spec: StepSpec, current: str | None, first_index: int
) -> tuple[list[Step], str | None]:
    """The steps of ``spec`` (a change_tool) from the tool ``current``, numbered from
    ``first_index``, and the tool mounted after them."""
    target: str = spec.args.tool
    if target == current:
        return [], current
    changer = cell.tool_changer
    # the task check refuses change_tool without a tool changer and a mounted tool
    assert changer is not None and current is not None
    d = changer.approach
    path = spec.path
    macro = Macro("change_tool", target)
    tcp_a = cell.tools[current].tcp.matrix()
    tcp_b = cell.tools[target].tcp.matrix()
    T_rack_a = frame_pose(cell, changer.rack[current])
    # where A's TCP is when B's TCP is at rack[B] (the bare flange carries A's TCP frame)
    T_rack_b = frame_pose(cell, changer.rack[target]) @ np.linalg.inv(tcp_b) @ tcp_a
    back = geometry.pose_matrix((0, 0, -d))
    rows = [
        (
            "approach",
            f"rack[{current}]",
            ApproachArgs(to=changer.rack[current], distance=d),
            T_rack_a @ back,
            current,
        ),
        ("descend", f"rack[{current}]", LinearArgs(to=changer.rack[current]), T_rack_a, current),
        ("tool_unlock", current, GripArgs(confirm=changer.locked, timeout=2.0), None, None),
        ("retreat", f"rack[{current}]", DistanceArgs(distance=d), None, None),
        (
            "approach",
            f"rack[{target}]",
            ApproachArgs(to=changer.rack[target], distance=d),
            T_rack_b @ back,
            None,
        ),
        ("descend", f"rack[{target}]", LinearArgs(to=changer.rack[target]), T_rack_b, None),
        ("tool_lock", target, GripArgs(confirm=changer.locked, timeout=2.0), None, target),
        ("retreat", f"rack[{target}]", DistanceArgs(distance=d), None, target),
    ]
    steps = [
        Step(
            first_index + i,
            StepKind(kind),
            name,
            args,
            path,
            macro,
            T,
            extra={"tool": tool, "tcp_of": current, "lock_output": changer.lock},
        )
        for i, (kind, name, args, T, tool) in enumerate(rows)
    ]
    return steps, target


__all__ = ["expand_change_tool"]
