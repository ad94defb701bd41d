"""Where a cell's cycle goes, and why a cycle-time target is out of reach (bench_cycle.py).

cellrunner's planned cycle and the blended PolyScope program's, per category (a blend's
saving split between its two moves; cellrunner's arc into a straight step belongs to the
joint move):

- **fixed**: grip, release, IO, waits (the same figures in both);
- **force steps**: ``move_until_contact`` / ``insert`` at the step's speed;
- **straight moves**, with the time cellrunner runs them at the TCP cap (a ``movel`` at
  that speed takes as long);
- **direct joint moves**: a straight line in joint space, which ``movej`` already times
  optimally (synchronised trapezoid on the slowest joint): only their blended ends differ;
- **joint moves with via points** (the direct line collides), with the path length
  against the direct line: here time-optimal timing and corner arcs can gain.

Then the joins where the arm stops and why (a grip, weighing the part, a force step's
standing start), and for each missed target how much would have to go and what share
that is of the time not spent on fixed steps, force steps or at the TCP cap.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: a straight move's sample runs at the TCP cap when within this fraction of it
CAPPED_FRACTION = 0.98


CATEGORIES = ("fixed", "force", "straight", "direct", "detour")
NAMES = {
    "fixed": "grip/release/IO/waits",
    "force": "force steps",
    "straight": "straight moves",
    "direct": "direct joint moves",
    "detour": "joint moves with via points",
}


@dataclass(frozen=True)
class Breakdown:
    ours_s: dict[str, float]  # per category (CATEGORIES), cellrunner's time
    polyscope_s: dict[str, float]  # the same for the blended PolyScope program
    tcp_capped_s: float  # of cellrunner's straight moves, the time at the TCP cap
    detours: list[str]  # one line per joint move through via points
    stops: list[str]  # joins where the arm stops, with the reason
    blends: int  # PolyScope's blended waypoints
    blend_saving_s: float  # the time they save


def category(step, taught) -> str:
    """The category (CATEGORIES) of a step of the plan."""
    from cellrunner.model.step import FORCE_KINDS, LINEAR_KINDS

    if not step.is_motion:
        return "fixed"
    if step.kind in FORCE_KINDS:
        return "force"
    if step.kind in LINEAR_KINDS:
        return "straight"
    return "direct" if len(taught[step.index][0]) <= 2 else "detour"


def breakdown(world, plan, taught, program) -> Breakdown:
    """The cycle of ``plan`` and of the blended PolyScope ``program`` (moves, their step
    labels, the time saved by the blend after each move, the fixed times) per category;
    ``taught``: per motion step index, its sharp-cornered waypoints and limits
    (bench_cycle.taught_waypoints). A blend's saving is split between its two moves."""
    from cellrunner.planning.timing import sample_measures

    kin, rate = world.kinematics, world.spec.rate_hz
    ours = dict.fromkeys(CATEGORIES, 0.0)
    capped = 0.0
    detours: list[str] = []
    by_label = {}
    for row in plan.rows:
        step = row.step
        kind = category(step, taught)
        by_label[step.label] = kind
        ours[kind] += row.duration_s
        if kind == "straight":
            _, _, tcp = sample_measures(
                kin, np.asarray(row.trajectory.q_rad), rate, rest_before=False, rest_after=False
            )
            capped += float((tcp >= CAPPED_FRACTION * taught[step.index][1].tcp_speed_mps).sum())
        elif kind == "detour" and row.duration_s > 0:
            waypoints = taught[step.index][0]
            edges = float(np.linalg.norm(np.diff(waypoints, axis=0), axis=1).sum())
            line = float(np.linalg.norm(waypoints[-1] - waypoints[0]))
            detours.append(
                f"{step.label[:40]}: {len(waypoints) - 2} via point(s), joint path "
                f"{edges:.2f} rad vs {line:.2f} rad direct (+{100 * (edges / line - 1):.0f}%)"
            )
    moves, labels, saved, fixed = program
    theirs = dict.fromkeys(CATEGORIES, 0.0)
    theirs["fixed"] = sum(fixed)
    ends = [0.0, *saved, 0.0]  # the saving before and after each move
    for i, (move, label) in enumerate(zip(moves, labels, strict=True)):
        theirs[by_label[label]] += move.duration_s - 0.5 * (ends[i] + ends[i + 1])
    blends = sum(1 for x in saved if x > 0)
    return Breakdown(ours, theirs, capped / rate, detours, _stops(plan), blends, sum(saved))


def _stops(plan) -> list[str]:
    """Each join between two motions, or a motion and a non-motion step, where the arm
    stands still, with the reason."""
    from cellrunner.model.step import FORCE_KINDS, LINEAR_KINDS

    rows = [r for r in plan.rows if r.duration_s > 0]
    out = []
    for i, row in enumerate(rows[:-1]):
        if not row.step.is_motion or not (row.verify_inputs or {}).get("ends_at_rest"):
            continue
        nxt = rows[i + 1]
        kind, following = row.step.kind, nxt.step.kind
        if not nxt.step.is_motion:
            reason = f"{following} follows"
        elif kind == "lift" and i > 0 and rows[i - 1].step.kind == "grip":
            reason = "the part is weighed at rest"
        elif following in FORCE_KINDS or kind in FORCE_KINDS:
            reason = "a force step starts and ends standing (wrist baseline, contact)"
        elif kind in LINEAR_KINDS and following in LINEAR_KINDS:
            reason = "two straight lines meet at a corner"
        else:
            reason = "different limits"
        out.append(f"after {row.step.label[:40]}: {reason}")
    return out


def why_lines(result: dict, b: Breakdown, targets: dict[str, float]) -> list[str]:
    """Lines explaining each missed target of ``result`` (bench_cycle.run) with numbers."""
    ours, theirs = b.ours_s, b.polyscope_s
    motion = [k for k in CATEGORIES[1:] if ours[k] or theirs[k]]
    lines = [
        f"    s, cellrunner/PolyScope blended: fixed {ours['fixed']:.2f}/{theirs['fixed']:.2f}, "
        f"motion {sum(ours[k] for k in motion):.2f}/{sum(theirs[k] for k in motion):.2f} ("
        + ", ".join(f"{NAMES[k]} {ours[k]:.2f}/{theirs[k]:.2f}" for k in motion)
        + f"); PolyScope's {b.blends} blends save {b.blend_saving_s:.2f} s, their summed "
        "accelerations not charged"
    ]
    if ours["straight"]:
        lines.append(
            f"    straight moves at the TCP cap (as long in a movel): {b.tcp_capped_s:.2f} s of "
            f"{ours['straight']:.2f} s"
        )
    if ours["direct"]:
        lines.append(
            f"    direct joint moves {ours['direct']:.2f} s: on a straight joint line movej's "
            "synchronised trapezoid is already the time-optimal profile; only their blended "
            "ends differ"
        )
    lines += [f"    detour: {d}" for d in b.detours]
    lines += [f"    stops {d}" for d in b.stops]
    same = ours["fixed"] + ours["force"] + b.tcp_capped_s
    for name, key, peer in (
        ("blended", "ratio_blended", "blended_s"),
        ("stopping", "ratio_stopping", "stopping_s"),
    ):
        if result[key] <= targets[name]:
            continue
        need = result["ours_s"] - targets[name] * result[peer]
        rest = result["ours_s"] - same
        lines.append(
            f"    {targets[name]}x PolyScope {name} needs {need:.2f} s less: "
            f"{100 * need / max(rest, 1e-9):.1f}% of the {rest:.2f} s not spent on fixed "
            f"steps, force steps or at the TCP cap"
        )
    return lines
