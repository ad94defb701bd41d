"""Look-ahead (a streamed motion advanced many periods per call, the physics in
``mujoco.rollout``) against the per-period loop: the same job gives the same outcome and
result code, the same fault at the same period, the same journal and step rows, the same
tracking error, and the same physics to the last bit. On the demo UR5e (500 Hz, one
physics step per period) and the CB3 UR5 shelf cell (125 Hz, four steps per period, a
``part_at`` input rule): a normal run, a collision with an obstacle only the twin knows
(a protective stop on contact), a part dropped in transit (2), a grip on nothing (no
part in the twin: the jaws close, the sensor never confirms, the grip times out and
retries; the shelf cell's wait for the part's input times out first), a grip on a part
too thin for the jaw sensor (the jaws hold it on the table while the grip times out:
those periods run one at a time, the part touching the table) and a weighing out of range (the task's force window above the part's weight:
the weigh after the lift fails and the pick retries). The holds (settle, jaws closing
and opening, weighing) are looked ahead as well as the motions."""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest

from cellrunner.execution.cell import CellController
from cellrunner.execution.journal import Journal
from cellrunner.execution.loop import ControlLoop
from cellrunner.execution.planner import job_planner
from cellrunner.model.codes import ResultCode
from cellrunner.model.geometry import Box, Placed
from cellrunner.model.load import load_cell, load_task
from cellrunner.planning.world import CellWorld

ROOT = Path(__file__).resolve().parents[2]
CELLS = {
    "demo_ur5e": ("cells/demo_ur5e.yaml", "tasks/pick_place.yaml", {"slot": 0}, "approach#2"),
    "shelf_ur5_cb3": (
        "cells/bin_to_shelf_ur5.yaml",
        "tasks/bin_to_shelf_ur5.yaml",
        {"slot": 0},
        "approach#2",  # the move home after it retraces it: no place on that one alone
    ),
    # a tool changer (two changes, its lock output off at the start with a tool mounted)
    # and the machine's input rules
    "cnc_changer_ur5e": ("cells/cnc_tending_ur5e.yaml", "tasks/cnc_tend.yaml", {}, "approach#2"),
    # suction cups: looked ahead while idle (suction off, nothing held)
    "palletizer_cups_ur10e": (
        "cells/palletizer_ur10e.yaml",
        "tasks/palletize.yaml",
        {"slot": 0},
        "approach#2",
    ),
}
#: the cells of the full fault matrix below (jaws, weighing)
JAW_CELLS = ("demo_ur5e", "shelf_ur5_cb3")


@dataclass
class Outcome:
    code: int
    message: str
    cycle_time_s: float
    records: tuple[Any, ...]
    journal: list[tuple[Any, ...]]
    tracking_error_m: float
    ticks: int
    ticks_ahead: int
    physics: bytes
    contact_s: float | None
    protective_stops: int
    parts: dict[str, list[float]]


class _SlipOnLift:
    """Arms ``part_slip`` as the first lift starts (the twin drops the part once it is
    in the air), as ``dry-run --inject part_slip@lift`` does."""

    def __init__(self) -> None:
        self.done = False

    def quiet_until_s(self, cell: CellController) -> float:
        # acts only when the step under way changes, which never happens inside a
        # look-ahead (a step ends in an ordinary tick)
        return float("inf")

    def __call__(self, cell: CellController) -> None:
        view = cell.job_view()
        if self.done or view is None or not view.step:
            return
        if next(r.kind for r in view.records if r.index == view.step) == "lift":
            cell.backend.inject_fault("part_slip")
            self.done = True


def _obstacle(world: CellWorld, plan: Any, kind: str) -> Placed:
    """A box where the TCP passes during the motion of kind ``KIND#N`` of the plan, and
    clear of the arm before it (at home and along the joint moves before): the twin has it,
    the planner does not. Halfway along the motion when that is clear, else the nearest
    of a few points around it: where the box may go depends on the path, not the test."""
    name, nth = kind.split("#")
    motions = [s for s in plan.steps if s.is_motion]
    step = [s for s in motions if s.kind == name][int(nth) - 1]
    before = [  # the joint moves before it (the straight ones may touch what they set down on)
        plan.nominal(s).trajectory.q_rad
        for s in motions[: motions.index(step)]
        if s.kind in ("move", "approach")
    ]
    q = plan.nominal(step).trajectory.q_rad
    for fraction in (0.5, 0.6, 0.4, 0.7, 0.3, 0.8, 0.2, 0.9, 0.1):
        T = np.eye(4)
        T[:3, 3] = world.kinematics.p_world_tcp(q[int(fraction * (len(q) - 1))])
        box = Placed("obstacle", Box((0.08, 0.08, 0.08)), T)
        model = world.with_obstacles(box).collision
        if model.is_valid(world.q_home_rad) and all(model.check_path(b).ok for b in before):
            return box
    raise AssertionError(f"no place on {kind} for an obstacle clear of the motions before it")


def _heavier_window(task_path: Path, tmp: Path) -> Path:
    """The task with its grip's force window well above any part's weight (N)."""
    text = task_path.read_text()
    heavier = re.sub(r"force: \{min: [0-9.]+, max: [0-9.]+\}", "force: {min: 300, max: 400}", text)
    assert heavier != text
    path = tmp / task_path.name
    path.write_text(heavier)
    return path


def _run(name: str, lookahead: bool, fault: str | None = None, tmp: Path | None = None) -> Outcome:
    from cellrunner.backends.sim.backend import SimBackend
    from cellrunner.sim.from_cell import description_of

    cell_path, task_path, params, collide_at = CELLS[name]
    cell = load_cell(ROOT / cell_path)
    if fault == "heavy":
        assert tmp is not None
        task = load_task(_heavier_window(ROOT / task_path, tmp), cell)
    else:
        task = load_task(ROOT / task_path, cell)
    world = CellWorld(cell)
    planner = job_planner(world)
    description = description_of(cell, (task,))
    if fault == "no_part":
        description = dataclasses.replace(description, parts=())
    if fault == "thin":  # the part is there but too thin: the jaws close on "nothing"
        thin = tuple(
            dataclasses.replace(p, shape=Box((0.001, 0.001, 0.05))) for p in description.parts
        )
        description = dataclasses.replace(description, parts=thin)
    if fault == "collision":
        from cellrunner.planning.job_plan import plan_job

        plan = plan_job(world, task, params, world.q_home_rad).task_plan
        description = dataclasses.replace(
            description, fixtures=(*description.fixtures, _obstacle(world, plan, collide_at))
        )
    backend = SimBackend(description)
    journal = Journal(":memory:")
    controller = CellController(cell, {1: task}, backend, journal, planner, wait_for_unhold=False)
    controller.setup()
    loop = ControlLoop(controller, lookahead=lookahead)
    loop.step(3)
    ticket = controller.start_job(1, params, "look-ahead", "cli")
    assert ticket.accepted, ticket.message
    loop.step(1)
    assert controller.wait_for_plan(timeout_s=600.0)
    if fault == "slip":
        loop.add_observer(_SlipOnLift())
    loop.run_job(max_s=120.0)
    result = controller.status().last_result
    view = controller.last_job
    assert result is not None and view is not None
    w = backend.world
    assert w is not None
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    physics = np.empty(mujoco.mj_stateSize(w.model, spec))
    mujoco.mj_getState(w.model, w.data, physics, spec)
    outcome = Outcome(
        code=result.result_code,
        message=result.result_text,
        cycle_time_s=result.cycle_time_s,
        records=view.records,
        journal=[row[:5] + row[6:] for row in journal.steps_of(result.job_id)],  # no wall time
        tracking_error_m=view.tracking_error_m,
        ticks=loop.ticks,
        ticks_ahead=loop.ticks_ahead,
        physics=physics.tobytes(),
        contact_s=None if w.last_contact is None else w.last_contact.time_s,
        protective_stops=controller.last_runner.protective_stops if controller.last_runner else 0,
        parts={p.name: w.part_pose_world(p.name)[:3, 3].tolist() for p in description.parts},
    )
    controller.close()
    return outcome


#: at most this fraction of a run's periods one at a time, the holds looked ahead
HELD_AHEAD = {None: 0.05, "no_part": 0.05, "heavy": 0.12}


@pytest.mark.parametrize("name", JAW_CELLS)
@pytest.mark.parametrize(
    ("fault", "code"),
    [
        (None, ResultCode.OK),
        ("collision", None),  # a stop on contact; resumed around it, or 100
        ("slip", ResultCode.PART_LOST),
        ("no_part", None),  # a grip on nothing (demo); the wait for a part times out (shelf)
        ("thin", ResultCode.NO_PART),
        ("heavy", ResultCode.NO_PART),
    ],
)
def test_look_ahead_gives_what_the_per_period_loop_gives(
    name: str, fault: str | None, code: ResultCode | None, tmp_path: Path
) -> None:
    per_period = _run(name, lookahead=False, fault=fault, tmp=tmp_path)
    ahead = _run(name, lookahead=True, fault=fault, tmp=tmp_path)
    assert code is None or per_period.code == code, per_period.message
    assert per_period.ticks_ahead == 0
    # the look-ahead really ran: most of a normal run's periods, a good part of the others
    assert ahead.ticks_ahead > (0.7 if fault is None else 0.2) * ahead.ticks
    if fault == "no_part":
        if name == "demo_ur5e":
            assert per_period.code == ResultCode.NO_PART
            assert "closed on nothing" in per_period.message
        else:  # the shelf cell waits for its part_in_tote input first
            assert per_period.code == ResultCode.STEP_TIMEOUT
            assert "part_in_tote did not read True" in per_period.message
    if fault == "thin":
        assert "closed on nothing" in per_period.message
    if fault == "heavy":
        assert "after lift is outside [300, 400] N" in per_period.message
    if fault in HELD_AHEAD:
        # the holds were looked ahead too: few periods one at a time (with motions alone:
        # 7.5-8.3% in a normal run, 22-24% with the weighing failing, 62-100% gripping on
        # nothing or waiting for a part that is not there)
        assert ahead.ticks - ahead.ticks_ahead < HELD_AHEAD[fault] * ahead.ticks
    if fault == "collision":
        assert per_period.contact_s is not None  # the twin stopped on the obstacle
        assert per_period.protective_stops >= 1
    for field in dataclasses.fields(Outcome):
        if field.name != "ticks_ahead":
            assert getattr(ahead, field.name) == getattr(per_period, field.name), field.name


@pytest.mark.parametrize(
    ("name", "fault", "ahead_share"),
    [
        ("cnc_changer_ur5e", None, 0.95),
        ("cnc_changer_ur5e", "collision", 0.2),
        ("cnc_changer_ur5e", "slip", 0.5),
        ("palletizer_cups_ur10e", None, 0.6),  # carrying on the cups: period by period
        ("palletizer_cups_ur10e", "collision", 0.2),
        ("palletizer_cups_ur10e", "slip", 0.3),
    ],
)
def test_tool_changer_and_suction_cells_are_looked_ahead_to_the_last_bit(
    name: str, fault: str | None, ahead_share: float, tmp_path: Path
) -> None:
    """A tool changer steady (lock on with a tool mounted, or off with it away from its
    rack place) and idle suction cups are looked ahead, and give what the per-period loop
    gives, to the last bit of the physics."""
    per_period = _run(name, lookahead=False, fault=fault, tmp=tmp_path)
    ahead = _run(name, lookahead=True, fault=fault, tmp=tmp_path)
    if fault is None:
        assert per_period.code == ResultCode.OK, per_period.message
    if fault == "slip":
        assert per_period.code == ResultCode.PART_LOST, per_period.message
    if (name, fault) == ("cnc_changer_ur5e", "collision"):  # resumed into the box 3 times
        assert per_period.code == ResultCode.PROTECTIVE_STOP
        assert "more than 2 protective stops, all 3 with the TCP within" in per_period.message
        assert per_period.message.endswith("something there stops the arm each time")
    assert ahead.ticks_ahead > ahead_share * ahead.ticks
    for field in dataclasses.fields(Outcome):
        if field.name != "ticks_ahead":
            assert getattr(ahead, field.name) == getattr(per_period, field.name), field.name


@pytest.mark.parametrize(
    "inject", ["protective_stop@approach#2", "estop@approach#2", "grip_miss@grip"]
)
def test_dry_run_injections_report_the_same_with_and_without_look_ahead(inject: str) -> None:
    """The dry-run command itself (its observer applies the injection when its moment
    comes): the JSON report is the same with look-ahead and with ``--per-period``."""
    import json
    import subprocess
    import sys

    def dry_run(*extra: str) -> dict[str, Any]:
        r = subprocess.run(
            [sys.executable, "-m", "cellrunner.cli.main", "dry-run", "cells/demo_ur5e.yaml"]
            + ["tasks/pick_place.yaml", "--inject", inject, "--json", *extra],
            capture_output=True,
            text=True,
            cwd=ROOT,
            timeout=300,
        )
        assert r.returncode in (0, 1), r.stderr
        report: dict[str, Any] = json.loads(r.stdout)
        report.pop("real_time_factor")  # wall clock
        return report

    per_period, ahead = dry_run("--per-period"), dry_run()
    assert per_period["result_code"] in (0, 1, 101)
    assert ahead == per_period
