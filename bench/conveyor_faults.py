"""What a line does to the belt under a tracked pick, one job each on the twin (issue 34):
the belt ramped down by its drive while the arm follows the block, standing, ramped up
again (the arm must hold with it and the pick end 0); the belt stopped at once and an
encoder jump of 50 mm (the arm cannot follow either: a controlled stop, 100).

Used by ``bench/bench_conveyor.py``, which prints the table; each row gives the result
and its text, the largest spread of the TCP's distance to the block along the belt while
the belt stood, and the arm's largest joint speed then (rad/s).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

#: the drive's ramp (m/s^2), how long the belt stands (s), the belt's speed (m/s)
RAMP_MPS2, STAND_S, SPEED_MPS = 2.0, 1.0, 0.30


class _Fault:
    """Acts once the arm follows the block (the TCP within 5 cm of it from above, moving
    along the belt faster than 0.25 m/s); then samples the arm while the belt stands."""

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self.acted_at_s: float | None = None
        self.restarted = False
        self.last: tuple[float, float] | None = None
        self.gaps_m: list[float] = []
        self.speeds: list[float] = []

    def __call__(self, cell: Any) -> None:
        world, backend = cell.backend.world, cell.backend
        if world is None:
            return
        tcp = world.tcp_pose_world()[:3, 3]
        block = world.part_pose_world("block")[:3, 3]
        if self.acted_at_s is None:
            last, self.last = self.last, (world.time_s, float(tcp[1]))
            if last is None or world.time_s <= last[0]:
                return
            vy = (float(tcp[1]) - last[1]) / (world.time_s - last[0])
            if np.linalg.norm(tcp[:2] - block[:2]) < 0.05 and vy > 0.25:
                if self.kind == "jump":
                    backend.jump_belt_encoder("belt", 0.05)
                else:
                    backend.set_belt_speed("belt", 0.0, RAMP_MPS2 if self.kind == "ramp" else None)
                self.acted_at_s = world.time_s
            return
        still_from = self.acted_at_s + SPEED_MPS / RAMP_MPS2 + 0.1
        if still_from < world.time_s < still_from + STAND_S - 0.1:
            self.gaps_m.append(float(tcp[1] - block[1]))
            self.speeds.append(float(np.abs(world.measure().qd_rad_s).max()))
        if self.kind == "ramp" and not self.restarted and world.time_s >= still_from + STAND_S:
            backend.set_belt_speed("belt", SPEED_MPS, RAMP_MPS2)
            self.restarted = True


def rehearse_one(
    cell_path: Any, task_path: Any, observer: Any, belt_mps: float | None = None
) -> tuple[Any, float]:
    """One job of the reference task on the twin, ``observer`` called every period (and
    the belt at ``belt_mps`` when given): the job and its wall time, s."""
    from cellrunner.backends.factory import make_backend
    from cellrunner.cli.common import console
    from cellrunner.execution.rehearsal import start_rehearsal
    from cellrunner.model.job_steps import job_steps
    from cellrunner.model.load import load_cell, load_task

    cell = load_cell(cell_path)
    task = load_task(task_path, cell)
    backend = make_backend(cell, "sim", tasks=(task,), rehearsed=[{}])
    rehearsal = start_rehearsal(cell, task, backend, console())
    try:
        if belt_mps is not None:
            backend.set_belt_speed("belt", belt_mps)
        rehearsal.loop.add_observer(observer)
        t0 = time.perf_counter()
        job = rehearsal.rehearse({}, job_steps(task, cell.cell, {}))
        return job, time.perf_counter() - t0
    finally:
        rehearsal.close()


def run_fault(kind: str, cell_path: Any, task_path: Any) -> dict[str, Any]:
    """One job of the reference task with the line's ``kind`` of fault: ramp, stop, jump."""
    fault = _Fault(kind)
    job, wall_s = rehearse_one(cell_path, task_path, fault)
    gaps = np.asarray(fault.gaps_m) * 1000
    return {
        "kind": kind,
        "acted": fault.acted_at_s is not None,
        "result": int(job.code),
        "text": str(job.payload.get("result_text", "")),
        "spread_mm": float(gaps.max() - gaps.min()) if len(gaps) else float("nan"),
        "still_rad_s": max(fault.speeds) if fault.speeds else float("nan"),
        "wall_s": wall_s,
    }


#: each fault and the result a line expects of it
EXPECTED = {"ramp": 0, "stop": 100, "jump": 100}
