"""The fault channel's conveyor commands (SPEC section 13): what a test or an engineer
does to the twin's belts and asks of its parts.

- ``parts`` -> ``ok {json: part name -> [x, y, z], world m}`` (the MuJoCo twin's parts
  that are in the cell, parked copies left out);
- ``belt NAME speed MPS [RAMP]`` -> the belt runs at MPS from the next period (0 stops
  it), or gets there along a drive's ramp of RAMP m/s^2;
- ``belt NAME jump M`` -> an encoder fault: the belt's encoder reading jumps by M m while
  the belt runs on;
- ``belt NAME travel`` -> the belt's travel so far, m, as its encoder reads it: what a
  test's PLC counts for a belt whose encoder the PLC reads (``source: plc``).
"""

from __future__ import annotations

import json
from typing import Any

__all__ = ["CONVEYOR_COMMANDS", "conveyor_command"]

CONVEYOR_COMMANDS = frozenset({"parts", "belt"})
#: a part further than this from the cell's origin is parked (a feed's spare), m
PARKED_M = 50.0


def conveyor_command(physics: Any, cmd: str, args: list[str]) -> str:
    """Execute ``cmd`` (one of :data:`CONVEYOR_COMMANDS`) on ``physics``; its reply text.
    Raises ValueError naming the valid choices."""
    world = getattr(physics, "world", None)
    if world is None or not world.built:
        raise ValueError("this physics has no parts nor belts (start the twin with a cell)")
    if cmd == "parts":
        out = {}
        for name, body in world.ids.part_bodies.items():
            xyz = [round(float(v), 4) for v in world.data.xpos[body]]
            if max(abs(xyz[0]), abs(xyz[1])) < PARKED_M:
                out[name] = xyz
        return json.dumps(out)
    belts = world.belts
    known = sorted(belts.descs) if belts is not None else []
    usage = "usage: belt NAME speed MPS [RAMP_MPS2] | belt NAME jump M | belt NAME travel"
    if len(args) == 2 and args[1] == "travel":
        if belts is None or args[0] not in belts.descs:
            raise ValueError(f"unknown belt {args[0]!r}; known: {', '.join(known) or 'none'}")
        return f"{belts.travel_m(args[0]):.6f}"
    if not (len(args) == 3 or (len(args) == 4 and args[1] == "speed")) or args[1] not in (
        "speed",
        "jump",
    ):
        raise ValueError(usage)
    if belts is None or args[0] not in belts.descs:
        raise ValueError(f"unknown belt {args[0]!r}; known: {', '.join(known) or 'none'}")
    value = float(args[2])
    if args[1] == "speed":
        belts.set_speed(args[0], value, float(args[3]) if len(args) == 4 else None)
    else:
        belts.jump_encoder(args[0], value)
    return f"belt {args[0]} {args[1]} {value:g}"
