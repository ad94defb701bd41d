"""Tight fits (SPEC section 12): a ``descend`` or ``insert`` may name the fixtures its tool
or held part may touch along its line (``contact: [FIXTURE, ...]``, the walls of a hole)
and the clearance it keeps from everything else (``clearance: m``, default the cell's).

A named fixture may be touched and pressed into by ``TIGHT_PRESS_M`` at most, by the tool
and by the held part, anywhere along the line, and along the straight move that leaves it (the
retreat after a release in the hole), which starts where the line ended. Every other pair
keeps the step's clearance.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from cellrunner.planning.collision import ContactAllowance

if TYPE_CHECKING:
    from cellrunner.model.body import Body
    from cellrunner.model.step import Step

#: how far the tool or held part may press into a fixture named in ``contact`` (m)
TIGHT_PRESS_M = 0.001


def named_contacts(step: Step | None) -> tuple[ContactAllowance, ...]:
    """The contact allowances of the fixtures ``step`` names in ``contact:``."""
    names = getattr(step.args, "contact", None) if step is not None else None
    return tuple(
        ContactAllowance(name, who, -TIGHT_PRESS_M)
        for name in names or ()
        for who in ("tool", "part")
    )


def step_clearance_m(step: Step | None) -> float | None:
    """The clearance ``step`` keeps (its ``clearance:``), or None for the cell's."""
    value = getattr(step.args, "clearance", None) if step is not None else None
    return None if value is None else float(value)


def line_end_hint(fixtures: list[Body], distance_m: float) -> str:
    """The fix for a straight line that ends within the clearance of ``fixtures`` (the
    closest ``distance_m`` away there): it is meant to end there (a hole's mouth, a nest)
    unless the frame is wrong."""
    names = ", ".join(f.name for f in fixtures)
    keep = max(0.0, distance_m - 0.0002)
    return (
        f"fix: the line ends within the clearance of {', '.join(fixtures)} "
        f"({distance_m * 1000:.2f} mm away there); if it is meant to go there (a hole's "
        f"walls, a nest), name them in the step's contact: [{names}], or give the step "
        f"clearance: {_metres(keep)}; otherwise move the frame"
    )


def _metres(value_m: float) -> str:
    return f"{float(f'{value_m:.4f}'):g}"
