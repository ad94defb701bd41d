"""Writing the report folder of a dry-run: JSON, pictures, plots, slot table, index.html."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.model.step import StepKind
from cellrunner.report import plots
from cellrunner.report.recorder import RunRecorder
from cellrunner.report.slots import SlotCycle, slot_cycles

if TYPE_CHECKING:
    from cellrunner.model.load import LoadedTask
    from cellrunner.model.params import ParamValue
    from cellrunner.planning.world import CellWorld
    from cellrunner.report.recorder import Mark
    from cellrunner.sim.world import SimWorld

#: plot files every report has (rendered pictures need an OpenGL backend; these do not)
PLOT_FILES = ("tcp_path.png", "joints.png", "timelines.png", "slots.png")
#: written into a report that has plots but no rendered pictures
NO_PICTURES = "NO_PICTURES.txt"


def write_report(
    folder: Path,
    recorder: RunRecorder,
    payload: dict[str, Any],
    *,
    sim_world: SimWorld,
    world: CellWorld,
    task: LoadedTask,
    params: dict[str, ParamValue],
    step_rows: list[dict[str, Any]],
    obstacles_m: np.ndarray | None = None,
) -> bool:
    """Write the report of one dry-run into ``folder``; returns whether it holds rendered
    pictures. ``sim_world``: the twin's SimWorld as the run left it; ``world``: the
    planning CellWorld; ``step_rows``: the --json step rows of the run; ``obstacles_m``:
    a watched cell's voxels occupied at any time of the run (world centres)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "result.json").write_text(json.dumps(payload, indent=2))
    title = f"{payload['task']} on {payload['cell']}"
    rows = _with_planned(world, task, params, step_rows)
    slots = slot_cycles(world, task, params)
    plot_list: list[tuple[str, str]] = []
    step_points: list[tuple[str, np.ndarray]] = []
    if recorder.t:
        a = recorder.arrays()
        marks = recorder.step_marks()
        step_points = _step_points(a, marks)
        fixtures = world.loaded.fixture_shapes()
        base = world.kinematics.T_world_base[:3, 3]
        plots.plot_tcp_path(
            folder / "tcp_path.png",
            a["tcp"],
            fixtures,
            base,
            step_points,
            f"{title}: TCP path",
            obstacles_m,
        )
        plots.plot_joints(
            folder / "joints.png", a["t"], a["q"], a["qd"], a["q_cmd"], marks, f"{title}: joints"
        )
        io = {name: np.array(values) for name, values in recorder.io.items()}
        plots.plot_timelines(
            folder / "timelines.png",
            a["t"],
            a["force"],
            io,
            marks,
            f"{title}: wrist force and IO",
            _force_window(task),
        )
        plot_list += [
            (
                "tcp_path.png",
                "TCP path over the fixtures: top, side and front; steps labelled where they start",
            ),
            ("timelines.png", "wrist force magnitude and every IO signal against time"),
            ("joints.png", "joint positions (commanded dashed) and speeds"),
        ]
    if slots is not None:
        name, slot_rows = slots
        plots.plot_slot_cycles(
            folder / "slots.png",
            [(r.slot, r.cycle_s) for r in slot_rows],
            name,
            f"{title}: planned cycle per {name} (worst in red)",
        )
        plot_list.append(("slots.png", f"planned cycle time per {name}"))
        _write_slots_csv(folder / "slots.csv", name, slot_rows)
    views, notes = _render_views(folder, recorder, sim_world, world, step_points)
    from cellrunner.report.page import write_index

    write_index(folder, payload, rows, views, plot_list, slots, notes)
    (folder / NO_PICTURES).unlink(missing_ok=True)
    if not views:
        (folder / NO_PICTURES).write_text(notes[0] + "\n" if notes else "no pictures\n")
    return bool(views)


def _with_planned(
    world: CellWorld,
    task: LoadedTask,
    params: dict[str, ParamValue],
    step_rows: list[dict[str, Any]],
) -> list[dict[str, Any]]:
    """The run's step rows with each step's planned duration (s) beside the simulated one
    (a joined, non-stop group of moves is cut into one piece per step when planned)."""
    from cellrunner.planning.job_plan import plan_job

    plan = plan_job(world, task, params, world.q_home_rad)
    planned = {r.step.index: r.duration_s for r in plan.task_plan.rows}
    return [{**r, "planned_s": planned.get(r["index"], 0.0)} for r in step_rows]


def _step_points(a: dict[str, np.ndarray], marks: list[Mark]) -> list[tuple[str, np.ndarray]]:
    """Where the TCP was as each step started (first attempt of each)."""
    seen: set[int] = set()
    out: list[tuple[str, np.ndarray]] = []
    for t, index, kind, _name in marks:
        if index in seen:
            continue
        seen.add(index)
        k = min(int(np.searchsorted(a["t"], t)), len(a["t"]) - 1)
        out.append((f"{index} {kind}", a["tcp"][k]))
    return out


def _force_window(task: LoadedTask) -> tuple[float | None, float | None] | None:
    for spec in task.steps:
        grip = getattr(spec.args, StepKind.GRIP, None) or (
            spec.args if spec.kind == StepKind.GRIP else None
        )
        force = getattr(grip, "force", None)
        if force is not None:
            return getattr(force, "min", None), getattr(force, "max", None)
    return None


def _write_slots_csv(path: Path, name: str, rows: list[SlotCycle]) -> None:
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow([name, "cycle_s", "error"])
        for r in rows:
            w.writerow([r.slot, "" if r.cycle_s is None else f"{r.cycle_s:.4f}", r.error])


def _render_views(
    folder: Path,
    recorder: RunRecorder,
    sim_world: SimWorld,
    world: CellWorld,
    step_points: list[tuple[str, np.ndarray]],
) -> tuple[list[tuple[str, str]], list[str]]:
    """Top and 3/4 views at the end, and the 3/4 view at the recorded moments (grip,
    release); returns (file, caption) pairs and notes (why there are none)."""
    from cellrunner.report.views import choose_shots, render_shot
    from cellrunner.sim.render import RenderUnavailable

    if sim_world is None or not recorder.tcp:
        return [], []
    tcp = np.array(recorder.tcp)
    fixtures = world.loaded.fixture_shapes()
    base = world.kinematics.T_world_base[:3, 3]
    fovy = float(sim_world.model.vis.global_.fovy)
    top, side = choose_shots(tcp, base, world.spec.reach_m, fixtures, fovy)
    out: list[tuple[str, str]] = []
    try:
        render_shot(
            sim_world,
            top,
            folder / "top.png",
            tcp,
            step_points,
            "top view at the end (x to the right, y up; TCP path in red)",
        )
        out.append(("top.png", "from above: the TCP path and where each step starts"))
        render_shot(
            sim_world,
            side,
            folder / "end.png",
            tcp,
            step_points,
            f"3/4 view at the end (azimuth {side.view.azimuth_deg:.0f} deg)",
        )
        out.append(("end.png", "3/4 view, chosen where fixtures hide the least of the work"))
        final_q = sim_world.data.qpos.copy()
        try:
            for name, qpos in recorder.moments:
                _pose(sim_world, qpos)
                render_shot(
                    sim_world,
                    side,
                    folder / f"{name}.png",
                    tcp,
                    step_points,
                    name.replace("_", " "),
                )
                out.append((f"{name}.png", name.replace("_", " ")))
        finally:
            _pose(sim_world, final_q)
    except RenderUnavailable as exc:
        return [], [str(exc)]
    return out, []


def _pose(sim_world: SimWorld, qpos: np.ndarray) -> None:
    """Put the scene in a recorded pose for a picture (kinematics only; the run is over)."""
    from cellrunner.sim.mujoco_loader import load_mujoco

    mujoco = load_mujoco()
    sim_world.data.qpos[:] = qpos
    mujoco.mj_forward(sim_world.model, sim_world.data)
