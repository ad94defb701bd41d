"""``cellrunner twin CELL [--host 127.0.0.2]``: a virtual UR controller (Dashboard 29999,
RTDE 30004, script 30001-30003, fault channel 29990) backed by the cell's MuJoCo twin, so
that ``run``/``serve --backend ur`` and the unmodified ur_rtde client work without an arm."""

from __future__ import annotations

import argparse
import contextlib
import sys
import threading
from typing import TYPE_CHECKING

import numpy as np

from cellrunner.cli.stopping import stop_on_signals
from cellrunner.model.load import load_cell

if TYPE_CHECKING:
    from cellrunner.model.robots import RobotSpec


def run(args: argparse.Namespace) -> int:
    cell = load_cell(args.cell)
    for w in cell.warnings:
        sys.stderr.write(f"{w}\n")
    from cellrunner.sim.from_cell import description_of
    from cellrunner.twin.mujoco_physics import MujocoPhysics
    from cellrunner.twin.server import run_twin

    # SIGTERM and Ctrl-C end the twin within 2 s, whatever its clients do
    signals = contextlib.ExitStack()
    stop, ready = signals.enter_context(stop_on_signals(exit_code=0)).event, threading.Event()
    if cell.cell.cameras:
        from cellrunner.sim.mujoco_loader import enable_pictures

        enable_pictures()  # before MuJoCo is imported; without GL a grab says so
    physics = MujocoPhysics(description_of(cell))
    spec = cell.spec
    cameras = None
    if cell.cell.cameras:
        from cellrunner.twin.camera import CameraServer

        physics.reset(np.radians(cell.cell.robot.home))  # builds the world the cameras see
        intruders = physics.world.intruders
        if intruders is not None:  # sim: intruders count from the twin's start
            intruders.start(physics.world.time_s)
        cameras = CameraServer(physics, args.host)
        cameras.start()
    threading.Thread(
        target=_announce, args=(ready, stop, args.host, spec, cameras is not None), daemon=True
    ).start()
    g = cell.cell.tool.gripper
    if g is not None and g.kind == "robotiq" and g.close is None:
        from cellrunner.backends.robotiq import serve_robotiq

        physics.reset(
            np.radians(cell.cell.robot.home)
        )  # builds the world the gripper socket drives
        threading.Thread(
            target=serve_robotiq, args=(args.host, physics.world, stop, g.port), daemon=True
        ).start()
    try:
        run_twin(
            spec,
            host=args.host,
            physics=physics,
            stop_event=stop,
            ready=ready,
            q_initial_rad=tuple(np.radians(cell.cell.robot.home)),
        )
    finally:
        if cameras is not None:
            cameras.stop()
        signals.close()
    return 0


def _announce(
    ready: threading.Event, stop: threading.Event, host: str, spec: RobotSpec, cameras: bool
) -> None:
    if ready.wait(timeout=60) and not stop.is_set():
        from cellrunner.twin.camera import CAMERA_PORT

        sys.stderr.write(
            f"virtual {spec.name.upper()} controller ({spec.generation}, {spec.rate_hz:g} Hz) on {host}: "
            "dashboard 29999, RTDE 30004, script 30001-30003, faults 29990"
            + (f", cameras {CAMERA_PORT}" if cameras else "")
            + "\n"
        )
