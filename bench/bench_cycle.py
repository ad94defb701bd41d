"""Cycle time on every reference cell: cellrunner vs the same job as a PolyScope program.

Run: ``python bench/bench_cycle.py [CELL [TASK]]`` from the repository root (default: every
``cells/*.yaml`` with each task of its ``tasks:`` map, default params), or
``python bench/run_all.py``.

For each job, four cycle times at the **same limits** (the cell's joint speed,
acceleration and TCP cap, x margin, as cellrunner plans with them):

- **cellrunner**: the planned cycle time (``check --json`` ``cycle_time_s``).
- **PolyScope, blended**: the program an integrator writes by hand, timed by the model in
  ``bench/polyscope.py`` (trapezoidal ``movej``/``movel``, UR's blend radii, the radii a
  good integrator uses; read that module's docstring). Its waypoints are the ones the
  integrator would teach: for each joint move, the goal and the via points that clear
  the obstacles (cellrunner's own collision-free path with its corners left sharp, before
  cellrunner rounds them); for each straight step one ``movel``.
- **PolyScope, stopping**: the same program with no blend radius (stop at every waypoint).
- **time-optimal bound**: the path cellrunner streams, timed continuously by TOPP-RA on a
  fine grid (:func:`cellrunner.planning.timing.optimal_duration_s`), rest to rest where
  cellrunner stops; what no sampling or safety headroom can beat on that path.

Grip, release, IO and waits take the same time in all four (cellrunner's figures).

With ``--optimal [--budget S]`` a fifth: the **optimal reference**
(``bench/optimal_reference.py``): every joint move's path replaced by the shortest one
OMPL's BIT* (path-length objective, same collision model and clearance, every edge
proven) finds in S seconds (default 10), corners rounded alike, both timed by the same
TOPP-RA. Its results are cached in ``var/bench-optimal.json`` (a run can be stopped and
resumed); on a loaded machine run it in the background, under ``nice``.

Targets (issue 27): cellrunner <= 0.92x blended, <= 0.85x stopping, <= 1.02x the bound,
<= 1.03x the optimal reference, on every cell.

The table and the targets are each task at its default parameters. ``--all-slots`` adds,
per task with an integer parameter (a pattern's slot, a kit's pocket), the range of each
ratio over every value of it: a slot whose path differs (another corner to round, a
wrist at the edge of its range) shows there and nowhere else.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import itertools
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
for _p in (REPO, REPO / "bench"):
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))

import cycle_breakdown  # noqa: E402
import polyscope  # noqa: E402

TARGET_BLENDED, TARGET_STOPPING, TARGET_BOUND, TARGET_OPTIMAL = 0.92, 0.85, 1.02, 1.03


def jobs(cell_arg: str | None = None, task_arg: str | None = None) -> list[tuple[str, str]]:
    """(cell, task) pairs: the ones given, else every reference cell with its tasks."""
    from cellrunner.model.load import load_cell

    if cell_arg and task_arg:
        return [(cell_arg, task_arg)]
    cells = (
        [cell_arg]
        if cell_arg
        else sorted(str(p.relative_to(REPO)) for p in (REPO / "cells").glob("*.yaml"))
    )
    out = []
    for cell_path in cells:
        with contextlib.redirect_stderr(io.StringIO()):
            loaded = load_cell(str(REPO / cell_path))
        for _, task in sorted(loaded.cell.tasks.items()):
            out.append((cell_path, str(loaded.resolve(task))))
    return out


def taught_waypoints(world, steps, q_start):
    """Per motion step index, the joint waypoints the planner found with corners left
    sharp (what an integrator teaches) and the step's limits."""
    from cellrunner.planning import joint_path, task_plan

    taught: dict[int, tuple[np.ndarray, object]] = {}
    original_motion, original_arcs = task_plan.StepPlanner.motion, joint_path._with_corner_arcs

    def recording(self, row, *args, **kwargs):
        motion = original_motion(self, row, *args, **kwargs)
        taught.setdefault(row.step.index, (np.array(motion.waypoints), motion.limits))
        return motion

    task_plan.StepPlanner.motion = recording
    # no arcs: every corner stays sharp and every edge is a straight piece (proven)
    joint_path._with_corner_arcs = lambda collision, q, *_, **__: (
        np.asarray(q, float),
        list(range(len(q) - 1)),
    )
    try:
        task_plan.plan_task(world, steps, q_start)
    finally:
        task_plan.StepPlanner.motion, joint_path._with_corner_arcs = original_motion, original_arcs
    return taught


def polyscope_program(world, plan, taught) -> tuple[list, list[float], list[float], list[str]]:
    """The moves of the hand-written program, the radius after each (blended), the fixed
    time of the non-motion steps, and a label per move."""
    from cellrunner.model.expand import LINEAR_KINDS

    kin, rate = world.kinematics, world.spec.rate_hz
    moves, stops_after, fixed, labels, vias = [], [], [], [], []
    rows = plan.rows
    for i, row in enumerate(rows):
        step = row.step
        if not step.is_motion:
            fixed.append(row.duration_s)
            if stops_after:
                stops_after[-1] = True
            continue
        waypoints, limits = taught[step.index]
        if step.kind in LINEAR_KINDS:
            parts = [polyscope.movel(kin, waypoints, limits, rate)]
        else:
            parts = [
                polyscope.movej(kin, a, b, limits, rate) for a, b in itertools.pairwise(waypoints)
            ]
        parts = [m for m in parts if m.duration_s > 0]
        weighed = (
            step.kind == "lift"
            and i > 0
            and rows[i - 1].step.kind == "grip"
            and getattr(rows[i - 1].step.args, "force", None) is not None
        )
        for k, move in enumerate(parts):
            moves.append(move)
            labels.append(step.label)
            last = k == len(parts) - 1
            vias.append(not last)
            stops_after.append(last and weighed)
    if stops_after:
        stops_after[-1] = True
    radii = [
        polyscope.blend_radius(m, n, stop=s, via=v)
        for m, n, s, v in zip(moves[:-1], moves[1:], stops_after[:-1], vias[:-1], strict=True)
    ]
    return moves, radii, fixed, labels


def optimal_bound_s(world, plan) -> float:
    """Motion time of the plan's own path timed continuously (TOPP-RA, fine grid), rest to
    rest where the plan stops, plus the plan's non-motion time."""
    from cellrunner.planning.timing import optimal_duration_s

    total, group, limits = 0.0, [], None
    for row in plan.rows:
        if not row.step.is_motion:
            total += row.duration_s
            continue
        q = np.asarray(row.trajectory.q_rad)
        group.append(q if not group else q[1:])
        limits = limits or _limits_of(world, row)
        if row.verify_inputs["ends_at_rest"]:
            total += optimal_duration_s(world.kinematics, np.vstack(group), limits)
            group, limits = [], None
    return total


def _limits_of(world, row):
    from cellrunner.planning.task_plan import StepPlanner

    q = row.trajectory.q_rad
    return StepPlanner(world, q[0], None).limits_for(row.step, (q[0], q[-1]))


def run(
    cell_path: str,
    task_path: str,
    verbose: bool = True,
    param_args: tuple[str, ...] = (),
    optimal_budget_s: float | None = None,
) -> dict:
    from cellrunner.cli.common import load, parse_params
    from cellrunner.planning.job_plan import plan_job
    from cellrunner.planning.world import CellWorld

    with contextlib.redirect_stderr(io.StringIO()):  # load warnings (e.g. users file)
        cell, task = load(str(REPO / cell_path), str(REPO / task_path))
    params = parse_params(list(param_args), task)
    world = CellWorld(cell)
    t = time.perf_counter()
    job = plan_job(world, task, params, world.q_home_rad, use_cache=False)
    plan_s = time.perf_counter() - t
    plan, steps = job.task_plan, list(job.steps)
    if not plan.ok:
        raise SystemExit(f"{cell_path} {task_path}: the task is infeasible: {plan.errors}")
    taught = taught_waypoints(world, steps, world.q_home_rad)
    moves, radii, fixed, labels = polyscope_program(world, plan, taught)
    rate = world.spec.rate_hz
    blended, saved = polyscope.program_time_s(moves, radii, rate)
    stopping, _ = polyscope.program_time_s(moves, [0.0] * len(radii), rate)
    blended += sum(fixed)
    stopping += sum(fixed)
    bound = optimal_bound_s(world, plan)
    ours = plan.cycle_time_s
    optimal = None
    if optimal_budget_s is not None:
        import optimal_reference

        if verbose:
            print(
                f"  {cell_path} {Path(task_path).name}: optimal reference (BIT*, {optimal_budget_s:g} s a move)"
            )
        optimal = optimal_reference.reference(
            world,
            plan,
            steps,
            f"{cell.digest}|{task.source.digest}|{params}",
            optimal_budget_s,
            verbose,
        )
    if verbose:
        print(f"  {cell_path} {Path(task_path).name} {params}: PolyScope program")
        ends = [0.0] if moves else []  # no blend after the last move
        for move, label, r, s in zip(moves, labels, radii + ends, saved + ends, strict=True):
            print(
                f"    {move.kind} {label[:40]:40s} {move.duration_s:6.2f} s   blend {r * 1000:5.0f} mm saves {s:5.2f} s"
            )
        for row in plan.rows:
            if row.step.is_motion:
                print(f"    cellrunner {row.step.label[:40]:40s} {row.duration_s:6.2f} s")
    return {
        "cell": cell_path,
        "task": task_path,
        "params": params,
        "ours_s": ours,
        "blended_s": blended,
        "stopping_s": stopping,
        "bound_s": bound,
        "plan_s": plan_s,
        "motion": bool(moves),
        "ratio_blended": ours / blended if moves else 1.0,
        "ratio_stopping": ours / stopping if moves else 1.0,
        "ratio_bound": ours / bound if bound > 0 else 1.0,
        "optimal": optimal,
        "breakdown": (
            cycle_breakdown.breakdown(world, plan, taught, (moves, labels, saved, fixed))
            if moves
            else None
        ),
    }


def run_all(
    cell: str | None = None,
    task: str | None = None,
    verbose: bool = True,
    optimal_budget_s: float | None = None,
) -> list[dict]:
    """Every job; one that cannot be timed (a param without default, infeasible) is
    listed with the reason instead of stopping the others."""
    from cellrunner.errors import CellrunnerError

    results = []
    for c, t in jobs(cell, task):
        try:
            results.append(run(c, t, verbose, optimal_budget_s=optimal_budget_s))
        except (CellrunnerError, SystemExit) as exc:
            results.append(
                {"cell": c, "task": t, "skipped": str(exc) or type(exc).__name__, "motion": False}
            )
    return results


def summary_lines(results: list[dict]) -> list[str]:
    lines = [
        f"cycle time, same limits (targets: <= {TARGET_BLENDED}x blended, <= {TARGET_STOPPING}x stopping, "
        f"<= {TARGET_BOUND}x bound)",
        f"  {'cell / task':44s} {'cellrunner':>10s} {'PS blend':>9s} {'ratio':>6s} {'PS stop':>8s} {'ratio':>6s} "
        f"{'bound':>7s} {'ratio':>6s}"
        + (f" {'opt ref':>8s} {'ratio':>6s}" if any(r.get("optimal") for r in results) else ""),
    ]
    for r in results:
        name = f"{Path(r['cell']).stem} / {Path(r['task']).stem}"
        if "skipped" in r:
            lines.append(f"  {name:44s} not timed: {r['skipped'][:120]}")
            continue
        if not r["motion"]:
            lines.append(f"  {name:44s} {r['ours_s']:9.2f}s   (no motion)")
            continue
        opt = r.get("optimal")
        lines.append(
            f"  {name:44s} {r['ours_s']:9.2f}s {r['blended_s']:8.2f}s {r['ratio_blended']:5.2f}x "
            f"{r['stopping_s']:7.2f}s {r['ratio_stopping']:5.2f}x {r['bound_s']:6.2f}s {r['ratio_bound']:5.3f}x"
            + (f" {opt['reference_s']:7.2f}s {opt['ratio']:5.3f}x" if opt else "")
        )
    optimal = [r for r in results if r.get("optimal")]
    if optimal:
        worst = max(optimal, key=lambda r: r["optimal"]["ratio"])
        lines.append(
            f"  worst vs the optimal reference: {Path(worst['cell']).stem} "
            f"{worst['optimal']['ratio']:.3f}x (target <= {TARGET_OPTIMAL}x)"
        )
        for r in optimal:
            if r["optimal"]["ratio"] > TARGET_OPTIMAL:
                lines.append(
                    f"  why {Path(r['cell']).stem} is {r['optimal']['ratio']:.3f}x the optimal reference:"
                )
                for m in r["optimal"]["moves"]:
                    if m["opt_s"] is not None and m["opt_s"] < m["ours_s"] - 1e-3:
                        lines.append(
                            f"    {m['step'][:44]:44s} ours {m['ours_length']:.3f} rad {m['ours_s']:.3f} s, "
                            f"BIT* {m['opt_length']:.3f} rad {m['opt_s']:.3f} s "
                            f"(+{m['ours_s'] - m['opt_s']:.3f} s)"
                        )
    missed = [r for r in results if r["motion"] and _missed(r)]
    if missed:
        lines.append("why, where a target is missed:")
    for r in missed:
        lines.append(f"  {Path(r['cell']).stem} / {Path(r['task']).stem}")
        lines += cycle_breakdown.why_lines(
            r, r["breakdown"], {"blended": TARGET_BLENDED, "stopping": TARGET_STOPPING}
        )
    return lines


def _missed(r: dict) -> bool:
    return (
        r["ratio_blended"] > TARGET_BLENDED
        or r["ratio_stopping"] > TARGET_STOPPING
        or r["ratio_bound"] > TARGET_BOUND
    )


def targets(results: list[dict]) -> list[tuple[str, bool]]:
    moving = [r for r in results if r["motion"]]
    return [
        ("cycle: every reference job timed", all("skipped" not in r for r in results)),
        (
            f"cycle <= {TARGET_BLENDED}x PolyScope blended",
            all(r["ratio_blended"] <= TARGET_BLENDED for r in moving),
        ),
        (
            f"cycle <= {TARGET_STOPPING}x PolyScope stopping",
            all(r["ratio_stopping"] <= TARGET_STOPPING for r in moving),
        ),
        (
            f"cycle <= {TARGET_BOUND}x time-optimal bound",
            all(r["ratio_bound"] <= TARGET_BOUND for r in moving),
        ),
        *(
            [
                (
                    f"cycle <= {TARGET_OPTIMAL}x the optimal reference",
                    all(r["optimal"]["ratio"] <= TARGET_OPTIMAL for r in moving),
                )
            ]
            if any(r.get("optimal") for r in moving)
            else []
        ),
    ]


def slot_ranges(cell: str | None = None, task: str | None = None) -> list[dict]:
    """Per job with an integer parameter: every value of its first one timed, and the range
    of each ratio over them."""
    from cellrunner.cli.common import load

    out = []
    for c, t in jobs(cell, task):
        with contextlib.redirect_stderr(io.StringIO()):
            _, loaded = load(str(REPO / c), str(REPO / t))
        ints = [(k, p) for k, p in (loaded.task.params or {}).items() if p.type == "int"]
        if not ints or ints[0][1].min is None or ints[0][1].max is None:
            continue
        name, p = ints[0]
        runs = [
            run(c, t, verbose=False, param_args=(f"{name}={v}",))
            for v in range(int(p.min), int(p.max) + 1)
        ]
        out.append({"cell": c, "task": t, "param": name, "runs": [r for r in runs if r["motion"]]})
    return out


def slot_lines(ranges: list[dict]) -> list[str]:
    lines = [
        "cycle time over every value of each task's integer parameter (ranges of the ratios):",
        f"  {'cell / task':44s} {'param':>7s} {'n':>3s} {'cellrunner s':>13s} {'vs PS blend':>12s} "
        f"{'vs PS stop':>12s} {'vs bound':>13s}",
    ]
    for r in ranges:
        runs = r["runs"]
        if not runs:
            continue

        def span(key: str, fmt: str, runs: list[dict] = runs) -> str:
            values = [x[key] for x in runs]
            return f"{min(values):{fmt}}-{max(values):{fmt}}"

        name = f"{Path(r['cell']).stem} / {Path(r['task']).stem}"
        lines.append(
            f"  {name:44s} {r['param']:>7s} {len(runs):3d} {span('ours_s', '.2f'):>13s} "
            f"{span('ratio_blended', '.3f'):>12s} {span('ratio_stopping', '.3f'):>12s} "
            f"{span('ratio_bound', '.3f'):>13s}"
        )
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cell", nargs="?")
    parser.add_argument("task", nargs="?")
    parser.add_argument(
        "--all-slots", action="store_true", help="also every value of each task's integer param"
    )
    parser.add_argument(
        "--optimal", action="store_true", help="also the optimal reference (BIT*, cached)"
    )
    parser.add_argument("--budget", type=float, default=10.0, help="BIT* seconds per move")
    args = parser.parse_args(argv)
    results = run_all(args.cell, args.task, optimal_budget_s=args.budget if args.optimal else None)
    print()
    print("\n".join(summary_lines(results)))
    if args.all_slots:
        print()
        print("\n".join(slot_lines(slot_ranges(args.cell, args.task))))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
