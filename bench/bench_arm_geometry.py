"""The arm's collision model: over-approximation against the meshes, self-collision speed.

Run from the repository root::

    PYTHONPATH=. python bench/bench_arm_geometry.py [--configs N]

Per model: the over-approximation the derivation measured (median and max mm of the
distance to the mesh of points on the parts' outer surface; see
``scripts/derive_arm_collision.py``), the number of convex parts and of checked self pairs,
and self-collision checks per second (``CollisionModel.is_valid`` on the bare arm at random
configurations). "Before" is the hand-drawn capsule model this replaced, measured with the
same loop on main at 21aa053 (load average about 8 on the 2-core machine); it is quoted, not
re-run, since the capsules are gone.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

#: self-collision checks per second with the capsule model (main 21aa053, same loop)
#: (UR5 and UR10 CB3: 0 of the 2000 configurations valid; the capsules overlapped)
CAPSULES_CHECKS_PER_S: dict[str, float] = {
    "ur3": 20932,
    "ur5": 27231,
    "ur10": 17477,
    "ur3e": 24118,
    "ur5e": 37411,
    "ur10e": 37474,
    "ur16e": 15426,
    "ur20": 30576,
    "ur30": 13712,
}


def checks_per_second(model: str, configs: int) -> tuple[float, int, int]:
    """(is_valid calls per second, parts, checked arm pairs) on the bare arm."""
    from cellrunner.model.robots import ROBOTS
    from cellrunner.planning.collision import CollisionModel
    from cellrunner.planning.kinematics import ArmKinematics

    world = CollisionModel(ArmKinematics(ROBOTS[model], np.eye(4), np.eye(4)))
    qs = np.random.default_rng(0).uniform(-math.pi, math.pi, (configs, 6))
    for q in qs[:20]:
        world.is_valid(q)
    start = time.perf_counter()
    for q in qs:
        world.is_valid(q)
    rate = configs / (time.perf_counter() - start)
    return rate, len(world._objects), len(world._pairs)


def run(configs: int = 2000) -> list[dict]:
    from cellrunner.model.arm_geometry import arm_geometry, available_models

    rows = []
    for model in available_models():
        figures = arm_geometry(model).over_approximation_mm
        rate, parts, pairs = checks_per_second(model, configs)
        rows.append(
            {
                "model": model,
                "median_mm": figures["median"],
                "max_mm": figures["max"],
                "parts": parts,
                "pairs": pairs,
                "checks_per_s": rate,
                "capsules_checks_per_s": CAPSULES_CHECKS_PER_S.get(model),
            }
        )
    return rows


def summary_lines(rows: list[dict]) -> list[str]:
    lines = []
    for r in rows:
        before = r["capsules_checks_per_s"]
        was = f" (capsules: {before:,.0f}/s)" if before else ""
        lines.append(
            f"arm model {r['model']}: over-approximation median {r['median_mm']:.2f} mm, "
            f"max {r['max_mm']:.1f} mm; {r['parts']} parts, {r['pairs']} self pairs checked; "
            f"{r['checks_per_s']:,.0f} self-collision checks/s{was}"
        )
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--configs", type=int, default=2000)
    args = parser.parse_args()
    for line in summary_lines(run(args.configs)):
        print(line)


if __name__ == "__main__":
    main()
