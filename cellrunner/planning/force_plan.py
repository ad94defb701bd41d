"""Planning the force steps: their straight line, and the contact they may make.

``move_until_contact`` runs to ``max_distance`` along its direction and ``insert`` to
``depth`` past its frame; ``check`` verifies the whole line. The contact the step is
for is allowed only where the line ends: the moving tool (or the carried part) may reach
into the fixtures it meets at the end of the line, by no more than it does there, and
every other pair (the arm, other fixtures) keeps the full clearance.
"""

from __future__ import annotations

import numpy as np

from cellrunner.model import geometry

#: contact allowed beyond the depth measured at the line's end (m)
CONTACT_SLACK_M = 0.001


def contact_line_goal(args, T_world_tcp: np.ndarray) -> np.ndarray:
    """The end of a move_until_contact line from ``T_world_tcp`` (full max_distance)."""
    d = np.asarray(args.direction, float) * args.max_distance
    if args.frame == "tool":
        return T_world_tcp @ geometry.pose_matrix(tuple(d))
    return geometry.pose_matrix(tuple(d)) @ T_world_tcp


def contact_allowances(planner, step, T_goal: np.ndarray) -> tuple:
    """Allowances for the fixtures the tool (or carried part) meets at the line's end."""
    from cellrunner.planning.collision import ContactAllowance

    try:
        q_end = planner.world.kinematics.ik_nearest(T_goal, planner.q)
    except Exception:  # unreachable: the line planner says why
        return ()
    allowances: list = []
    for _ in range(8):  # one pair per round, a line meets few
        model = planner.collision(tuple(allowances))
        clearance = model.clearance(q_end)
        mover = "part" if clearance.a.startswith("part '") else "tool" if clearance.a.startswith("tool ") else None
        if clearance.distance_m >= clearance.required_m or not clearance.b.startswith("fixture '") or mover is None:
            break
        fixture = clearance.b[len("fixture '"):-1]
        allowances.append(ContactAllowance(fixture, mover, min(clearance.distance_m, 0.0) - CONTACT_SLACK_M))
    return tuple(allowances)
