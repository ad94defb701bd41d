"""Joint-planning benchmark: cellrunner's planner vs pyroboplan's RRT-Connect, same problems.

Run: ``python bench/bench_planning.py [--reps 3]`` from the repository root (or all the
planning benches: ``python bench/run_all.py``). Scenes: bench/scenes.py (UR5e, cluttered
table, shelf, bins), 20 start/goal pairs: the headline figures and targets. ``--large``
adds 5 problems each for the other arms (a UR20 palletizing, a UR30 tending a machine through
its door, a UR15 at a tall rack, and the CB3 arms: a UR5 at the shelf, a UR10 at the rack),
reported per arm beside the headline.

Fairness: both planners solve each problem in the same process and run, on the identical
pinocchio model and collision geometry (the same capsules, tool, fixtures and checked
pairs) and the same 2 mm clearance. pyroboplan runs its RRT-Connect (``rrt_connect`` and
``bidirectional_rrt`` on) with its own defaults for everything else (0.05 rad discrete
edge checks, no goal bias, unlimited connection distance), its clearance as
``collision_distance_padding`` and seed 1; ours runs ``plan_joint_path`` with seed 1.
pyroboplan's planning time excludes path shortening (``plan`` does not shorten); its
``shortcut_path`` (defaults: 100 random tries) is timed separately and shown as
"+shortcut". Ours is planning as ``check`` runs it: the direct check, the search,
shortcutting and the corner arcs, all sampled every 0.1 rad (``proven=False``); where its
path then fails the proof (an obstacle between samples), that failed proof and the same
move planned again with every piece proven are counted in too (``+proven``), as ``check``
spends them. Beside it: "+proof", the conservative proof of the path's every piece
(nothing slips between checks; see cellrunner/planning/collision.py) that ``check``'s
verifier makes of every timed trajectory, whoever planned it, and which pyroboplan's 0.05
rad sampling does not do (here of the waypoints; the verifier proves the 500 Hz samples
of the same polyline); and "proven planner", ``plan_joint_path`` proving every piece
itself, as task planning did before the verifier's proof was made the only one.
Each problem is run ``--reps`` times per planner, interleaved, after one warm-up each
(imports); the per-problem time is the median of the repetitions.

Times are CPU time of this process (``time.process_time``): both planners are
single-threaded, and on a shared machine wall time mostly measures the other processes
(at load 14 on 2 cores the same runs took 5x longer by the wall clock).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from cellrunner.native_threads import one_thread_each

one_thread_each()  # as the command does: both planners measured with one BLAS thread

import numpy as np  # noqa: E402
from scenes import HOME_DEG, T_FLANGE_TCP, large_arm_scenes, scenes, tool  # noqa: E402

from cellrunner.errors import InfeasibleError  # noqa: E402
from cellrunner.model.robots import robot_spec  # noqa: E402
from cellrunner.planning.collision import CollisionModel  # noqa: E402
from cellrunner.planning.joint_path import plan_joint_path  # noqa: E402
from cellrunner.planning.kinematics import ArmKinematics  # noqa: E402

CLEARANCE_M = 0.002
SEED = 1


@dataclass
class Row:
    name: str
    model: str
    ours_s: float
    ours_ok: bool
    ours_how: str
    ours_proof_s: float
    ours_proven_s: float
    base_s: float | None = None
    base_ok: bool | None = None
    base_shortcut_s: float | None = None


#: arms whose scenes could not be built, and why (filled by problems())
SKIPPED: dict[str, str] = {}


def problems(large: bool = False):
    home = np.radians(HOME_DEG)
    for scene in (*scenes(), *(large_arm_scenes() if large else ())):
        kin = ArmKinematics(robot_spec(scene.model), np.eye(4), T_FLANGE_TCP)
        try:
            world = CollisionModel(kin, tool(), scene.fixtures, CLEARANCE_M)
        except InfeasibleError as exc:  # no collision geometry for this arm (no meshes)
            SKIPPED[scene.model] = str(exc)
            print(f"  (skipped scene {scene.name}: {exc})")
            continue
        q = {}
        for name, T in scene.targets:
            valid = [s for s in kin.ik_all(T, home) if world.is_valid(s)]
            if valid:
                q[name] = valid[0]
        for a, b in scene.problems:
            if a in q and b in q:
                yield f"{scene.name}:{a}->{b}", scene.model, kin, world, q[a], q[b]
            else:
                print(f"  (skipped {scene.name}:{a}->{b}: no collision-free IK)")


#: the clock of every planning time (module docstring)
CLOCK = time.process_time


def ours(world, q0, q1) -> tuple[bool, str, float, float, float]:
    """(ok, how, planning as check runs it, the proof of its path, the proven planner)."""
    try:
        t = CLOCK()
        path = plan_joint_path(world, q0, q1, time_budget_s=5.0, seed=SEED, proven=False)
        plan_s, how = CLOCK() - t, path.planner
        t = CLOCK()
        ok = world.check_path(path.q_rad).ok
        proof_s = CLOCK() - t
        t = CLOCK()
        proven = plan_joint_path(world, q0, q1, time_budget_s=5.0, seed=SEED)
        proven_s = CLOCK() - t
    except InfeasibleError:
        return False, "FAIL", float("nan"), float("nan"), float("nan")
    if not ok and path.loose is not None:  # as check: the path before its via points were pulled
        t = CLOCK()
        ok = world.check_path(path.loose()).ok
        plan_s, how = plan_s + proof_s + (CLOCK() - t), f"{how}+loose"
    if not ok:  # as check: the failed proof, then the move planned proven, then its proof
        t = CLOCK()
        world.check_path(proven.q_rad)
        plan_s, how, proof_s = plan_s + proof_s + proven_s, f"{how}+proven", CLOCK() - t
    return True, how, plan_s, proof_s, proven_s


def pyroboplan_runner():
    """A function (kin, world, q0, q1) -> (ok, plan_s, shortcut_s), or None and why not."""
    try:
        import contextlib
        import io

        from pyroboplan.planning.path_shortcutting import shortcut_path
        from pyroboplan.planning.rrt import RRTPlanner, RRTPlannerOptions
    except Exception as exc:  # report exactly why the baseline is missing
        return None, f"pyroboplan unavailable: {type(exc).__name__}: {exc}"

    def run(kin, world, q0, q1):
        options = RRTPlannerOptions(
            rrt_connect=True,
            bidirectional_rrt=True,
            rng_seed=SEED,
            collision_distance_padding=CLEARANCE_M,
            max_planning_time=10.0,
        )
        planner = RRTPlanner(kin.model, world.pinocchio_geometry, options)
        with contextlib.redirect_stdout(io.StringIO()):  # it prints progress
            t = CLOCK()
            path = planner.plan(q0, q1)
            plan_s = CLOCK() - t
            shortcut_s = None
            if path:
                t = CLOCK()
                shortcut_path(kin.model, world.pinocchio_geometry, path)
                shortcut_s = CLOCK() - t
        return bool(path), plan_s, shortcut_s

    return run, ""


def run(reps: int = 3, verbose: bool = True, large: bool = False) -> dict:
    """Plan every problem ``reps`` times with both planners; per-problem medians. The
    headline figures cover the UR5e problems; ``large`` adds the large arms' problems,
    summarised per arm under ``"arms"``."""
    cases = list(problems(large))
    baseline, why = pyroboplan_runner()
    # warm-up: imports (OMPL, pyroboplan) are not planning time
    _, _, kin, world, q0, q1 = cases[0]
    ours(world, q0, q1)
    if baseline is not None:
        try:
            baseline(kin, world, q0, q1)
        except Exception as exc:
            why, baseline = f"pyroboplan failed: {type(exc).__name__}: {exc}", None
    rows = []
    for name, model, kin, world, q0, q1 in cases:
        times, proofs, provens, base_times, short_times = [], [], [], [], []
        ok, how, base_ok = True, "", None
        for _ in range(reps):
            ok_r, how, t, proof_t, proven_t = ours(world, q0, q1)
            ok, times = ok and ok_r, times + [t]
            proofs, provens = proofs + [proof_t], provens + [proven_t]
            if baseline is not None:
                try:
                    b_ok, b_t, s_t = baseline(kin, world, q0, q1)
                except Exception as exc:
                    why, baseline = f"pyroboplan failed: {type(exc).__name__}: {exc}", None
                    continue
                base_ok = b_ok if base_ok is None else base_ok and b_ok
                base_times.append(b_t)
                if s_t is not None:
                    short_times.append(s_t)
        row = Row(
            name,
            model,
            statistics.median(times),
            ok,
            how if ok else "FAIL",
            statistics.median(proofs),
            statistics.median(provens),
            statistics.median(base_times) if base_times else None,
            base_ok,
            statistics.median(short_times) if short_times else None,
        )
        rows.append(row)
        if verbose:
            base = (
                ""
                if row.base_s is None
                else (
                    f"{row.base_s * 1000:9.1f} ms {'ok' if row.base_ok else 'FAIL'}"
                    + (
                        ""
                        if row.base_shortcut_s is None
                        else f"  +shortcut {row.base_shortcut_s * 1000:7.1f} ms"
                    )
                )
            )
            print(
                f"  {name:30s} {row.ours_how:17s} {row.ours_s * 1000:7.1f} ms "
                f"+proof {row.ours_proof_s * 1000:5.1f}  proven planner "
                f"{row.ours_proven_s * 1000:5.1f}   {base}",
                flush=True,
            )
    result = _summary([r for r in rows if r.model == "ur5e"], reps, why)
    result["arms"] = {
        model: _summary([r for r in rows if r.model == model], reps, why)
        for model in sorted({r.model for r in rows} - {"ur5e"})
    }
    result["arms_skipped"] = dict(SKIPPED)
    return result


def _summary(rows: list[Row], reps: int, why: str) -> dict:
    """Success, medians and the ratio to pyroboplan over ``rows``."""
    ours_t = [r.ours_s for r in rows]
    with_proof = [r.ours_s + r.ours_proof_s for r in rows]
    proven = [r.ours_proven_s for r in rows]
    result = {
        "problems": len(rows),
        "reps": reps,
        "ours_success": sum(r.ours_ok for r in rows),
        "ours_median_ms": statistics.median(ours_t) * 1000,
        "ours_p95_ms": float(np.percentile(ours_t, 95)) * 1000,
        "ours_direct": sum(r.ours_how == "direct" for r in rows),
        "ours_reproven": sum(r.ours_how.endswith("+proven") for r in rows),
        "ours_with_proof_median_ms": statistics.median(with_proof) * 1000,
        "ours_proven_median_ms": statistics.median(proven) * 1000,
        "baseline": why or "pyroboplan RRT-Connect",
    }
    base_t = [r.base_s for r in rows if r.base_s is not None]
    if len(base_t) == len(rows):
        short = [r.base_s + (r.base_shortcut_s or 0.0) for r in rows]
        result.update(
            base_success=sum(bool(r.base_ok) for r in rows),
            base_median_ms=statistics.median(base_t) * 1000,
            base_p95_ms=float(np.percentile(base_t, 95)) * 1000,
            base_shortcut_median_ms=statistics.median(short) * 1000,
            ratio=statistics.median(base_t) / statistics.median(ours_t),
            ratio_shortcut=statistics.median(short) / statistics.median(ours_t),
            ratio_with_proof=statistics.median(base_t) / statistics.median(with_proof),
            ratio_proven=statistics.median(base_t) / statistics.median(proven),
        )
    return result


def summary_lines(r: dict) -> list[str]:
    lines = [
        f"planning, {r['problems']} UR5e problems (table/shelf/bin), median of {r['reps']} runs "
        "each, CPU time:",
        f"  cellrunner   success {r['ours_success']}/{r['problems']}  median {r['ours_median_ms']:6.1f} ms  "
        f"p95 {r['ours_p95_ms']:6.1f} ms  (as check plans: sampled, shortened, rounded; "
        f"{r['ours_direct']} direct, {r['ours_reproven']} planned again proven)",
        f"  + the verifier's proof of the path: median {r['ours_with_proof_median_ms']:6.1f} ms;"
        f"  the proven planner alone: median {r['ours_proven_median_ms']:6.1f} ms",
    ]
    if "ratio" in r:
        lines += [
            f"  pyroboplan   success {r['base_success']}/{r['problems']}  median {r['base_median_ms']:6.1f} ms  "
            f"p95 {r['base_p95_ms']:6.1f} ms  (RRT-Connect, no shortening)",
            f"  pyroboplan + its shortcut_path: median {r['base_shortcut_median_ms']:6.1f} ms",
            f"  ratio pyroboplan / cellrunner (medians): {r['ratio']:.1f}x  "
            f"({r['ratio_shortcut']:.1f}x with its shortening; {r['ratio_with_proof']:.1f}x "
            f"counting our proof, which it does not make; {r['ratio_proven']:.1f}x the proven "
            "planner)",
        ]
    else:
        lines.append(
            f"  pyroboplan   MISSING: the ratio is not measured ({r['baseline']}); "
            "pip install pyroboplan"
        )
    for model, a in r.get("arms", {}).items():
        ratio = f"  {a['ratio']:.1f}x pyroboplan (medians)" if "ratio" in a else ""
        lines.append(
            f"  {model.upper():11s}  success {a['ours_success']}/{a['problems']}  median "
            f"{a['ours_median_ms']:6.1f} ms  p95 {a['ours_p95_ms']:6.1f} ms{ratio}"
        )
    for model, why in r.get("arms_skipped", {}).items():
        lines.append(f"  {model.upper():11s}  not planned: {why.split(':')[0]}")
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=3, help="runs per problem and planner (median)")
    parser.add_argument(
        "--large",
        action="store_true",
        help="add the other arms' problems (UR20, UR30, UR15, UR5, UR10; reported per arm)",
    )
    args = parser.parse_args(argv)
    result = run(args.reps, large=args.large)
    print()
    print("\n".join(summary_lines(result)))
    solved = [result, *result["arms"].values()]
    return 0 if all(r["ours_success"] == r["problems"] for r in solved) else 1


if __name__ == "__main__":
    raise SystemExit(main())
