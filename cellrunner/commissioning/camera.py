"""``calibrate-camera``'s session: the planned views become a task of joint moves that the
cell's own planner proves (limits x margin, collisions) and the cell controller streams
through ur_rtde, exactly as ``run`` does; between two moves, with the arm at rest, a gate
reads the arm's joints and grabs a picture.

A board on the flange (eye-to-hand) is added to the tool's collision geometry for this
session, so that every move keeps it clear of the fixtures and the arm.
"""

from __future__ import annotations

import dataclasses
import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cellrunner.errors import CellrunnerError
from cellrunner.model.camera import FLANGE, Camera
from cellrunner.model.load import LoadedCell, load_task
from cellrunner.vision.board import printed_size_m
from cellrunner.vision.views import View

#: the board slab's thickness, and the clearance kept around it, for planning (m)
BOARD_THICKNESS_M, BOARD_CLEARANCE_M = 0.003, 0.01


@dataclass
class Shot:
    """One view as taken: the measured joints (rad) and the picture."""

    q_rad: np.ndarray
    image: np.ndarray


def with_board(loaded: LoadedCell, camera: Camera) -> LoadedCell:
    """The cell with a flange-mounted board added to the tool geometry (as a box)."""
    board = camera.board
    if board is None or board.mount != FLANGE:
        return loaded
    from cellrunner.model.base import PlacedShape

    w, h = printed_size_m(board)
    pad = 2 * BOARD_CLEARANCE_M
    T = board.pose.matrix()
    centre = T[:3, :3] @ np.array([0.0, 0.0, -BOARD_THICKNESS_M / 2]) + T[:3, 3]
    box = PlacedShape.model_validate(
        {
            "box": {"size": [w + pad, h + pad, BOARD_THICKNESS_M + pad]},
            "xyz": [float(v) for v in centre],
            "rpy": list(board.pose.rpy),
        }
    )
    tool = loaded.cell.tool.model_copy(update={"geometry": [*loaded.cell.tool.geometry, box]})
    return dataclasses.replace(loaded, cell=loaded.cell.model_copy(update={"tool": tool}))


def views_task(views: list[View], folder: Path) -> Path:
    """A task file of one joint move per view, then home."""
    lines = ["task: calibrate_camera", "steps:"]
    for view in views:
        q = ", ".join(f"{v:.6f}" for v in np.degrees(view.q_rad))
        lines.append(f"  - move: [{q}]   # {view.label}")
    lines.append("  - move: home")
    path = folder / "calibrate_camera.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path


class ShotGate:
    """The job's gate: before step k+1 starts (the arm at rest after move k), takes shot k
    on a worker thread; the step starts once the shot is in. Never blocks the control
    thread."""

    def __init__(self, reader: Any, source: Any, views: int, on_fail: Any, say: Any):
        self.reader, self.source, self.views = reader, source, views
        self.on_fail, self.say = on_fail, say
        self.shots: list[Shot] = []
        self.error: Exception | None = None
        self._worker: threading.Thread | None = None
        self._for: int | None = None

    def __call__(self, step: Any) -> bool:
        k = step.index - 1  # the view the arm stands at
        if k < 1 or k > self.views:
            return True
        if self._for != k:
            self._for = k
            self._worker = threading.Thread(target=self._take, args=(k,), daemon=True)
            self._worker.start()
        if self._worker is not None and self._worker.is_alive():
            return False
        if self.error is not None:
            if self.on_fail is not None:
                self.on_fail()
                self.on_fail = None
            return False
        return True

    def _take(self, k: int) -> None:
        try:
            q = self.reader.read_q_rad()
            image = self.source.grab()
            q_after = self.reader.read_q_rad(samples=5)
            if np.max(np.abs(q_after - q)) > 1e-4:
                raise CellrunnerError(f"the arm moved while view {k} was taken")
            self.shots.append(Shot(q, image))
            self.say(f"  view {k}/{self.views}: picture taken")
        except Exception as exc:  # reported by the command after the job is aborted
            self.error = exc


def take_shots(
    loaded: LoadedCell, views: list[View], host: str, reader: Any, source: Any, say: Any
) -> list[Shot]:
    """Move through ``views`` (then home) as a job on the arm at ``host``; the shots."""
    from cellrunner.execution.assembly import assemble_cell
    from cellrunner.model.codes import ResultCode

    with tempfile.TemporaryDirectory(prefix="cellrunner-calibrate-") as folder:
        task = load_task(views_task(views, Path(folder)), loaded)
    controller: Any = None
    gate = ShotGate(reader, source, len(views), lambda: controller.command("abort"), say)
    assembled = assemble_cell(
        loaded, {1: task}, "ur", robot_host=host, use_cache=False, joined=False, gate=gate
    )
    controller, loop = assembled.controller, assembled.loop
    controller.setup()
    try:
        loop.step(5)
        ticket = controller.start_job(1, {}, "", "calibrate-camera")
        if not ticket.accepted:
            raise CellrunnerError(f"the calibration moves were refused: {ticket.message}")
        loop.run_job(max_s=1800.0)
        result = controller.status().last_result
    finally:
        controller.close()
    if gate.error is not None:
        raise gate.error
    if result.result_code is not ResultCode.OK:
        raise CellrunnerError(
            f"the calibration moves failed: {result.result_code} {result.result_text}"
        )
    return gate.shots
