"""`cellrunner jog` on a terminal, driven as a person would: tmux sends the keys (a held
key is its auto-repeat) and the screen is read back with capture-pane, against
`cellrunner twin` through ur_rtde. A jog toward a wall stops before contact; a jog into
the wrist singularity slows and stops; no protective stop in either."""

from __future__ import annotations

import json
import os
import shlex
import subprocess
import sys
import time

import numpy as np
import pytest

from tests.commissioning.conftest import fault, twin, write_project
from tests.conftest import ROOT

HOST = "127.0.0.154"
pytestmark = pytest.mark.skipif(
    not __import__("shutil").which("tmux"), reason="tmux missing (scripts/test installs it)"
)


class Terminal:
    def __init__(self, command: str):
        self.socket = f"cellrunner-jog-{os.getpid()}"
        self.tmux = ["tmux", "-L", self.socket]
        subprocess.run(
            [
                *self.tmux,
                "new-session",
                "-d",
                "-s",
                "jog",
                "-x",
                "200",
                "-y",
                "24",
                f"{command}; echo EXIT=$?; sleep 30",
            ],
            check=True,
            cwd=ROOT,
        )

    def keys(self, *keys: str) -> None:
        subprocess.run([*self.tmux, "send-keys", "-t", "jog", *keys], check=True)

    def screen(self) -> str:
        return subprocess.run(
            [*self.tmux, "capture-pane", "-p", "-t", "jog"],
            check=True,
            capture_output=True,
            text=True,
        ).stdout

    def wait_for(self, text: str, timeout_s: float) -> str:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            screen = self.screen()
            if text in screen:
                return screen
            time.sleep(0.1)
        raise AssertionError(f"{text!r} not on the screen:\n{self.screen()}")

    def hold(self, key: str, until: str, timeout_s: float, repeat_s: float = 0.03) -> list[str]:
        """Auto-repeat ``key`` until ``until`` shows in the status line; the screens seen."""
        screens = []
        deadline = time.monotonic() + timeout_s
        next_look = 0.0
        while time.monotonic() < deadline:
            self.keys(key)
            time.sleep(repeat_s)
            if time.monotonic() >= next_look:
                screens.append(self.screen())
                if until in _status(screens[-1]):
                    return screens
                next_look = time.monotonic() + 0.2
        raise AssertionError(f"{until!r} never in the status; last screen:\n{screens[-1]}")

    def close(self) -> None:
        subprocess.run([*self.tmux, "kill-server"], capture_output=True)


def _status(screen: str) -> str:
    return next((line for line in screen.splitlines() if line.startswith("status: ")), "")


def _state() -> dict:
    return json.loads(fault(HOST, "state"))


def test_jog_stops_before_the_wall_and_before_the_wrist_singularity(tmp_path):
    cell, _ = write_project(tmp_path)
    from cellrunner.model.load import load_cell
    from cellrunner.planning.world import CellWorld

    world = CellWorld(load_cell(cell))
    with twin(cell, HOST):
        term = Terminal(
            f"{shlex.quote(sys.executable)} -m cellrunner.cli.main jog {shlex.quote(str(cell))} "
            f"--robot-host {HOST} --mode base"
        )
        try:
            term.wait_for("cellrunner jog  mode: base  speed: 25%", 60)
            term.keys("+", "+")
            term.wait_for("speed: 100%", 5)
            # base -X is world +X here (the mount turns the base 180 deg): towards the wall
            screens = term.hold("a", until="stopped: ", timeout_s=40)
            assert any(_status(s).startswith("status: slowing (") for s in screens), (
                "it slows first"
            )
            assert "fixture 'wall'" in _status(screens[-1])
            q = np.array(_state()["q_rad"])
            assert _state()["safety_mode"] == "NORMAL"
            distances, _ = world.collision.pair_distances(q)
            to_wall = [
                d
                for d, (a, b) in zip(distances, world.collision.pair_labels, strict=True)
                if "'wall'" in a + b
            ]
            assert 0.0 < min(to_wall) < 0.12, "stopped before contact, near the wall"
            # dead-man: keys released -> stopped, the arm stays
            term.wait_for("status: stopped (no key held)", 3)
            q_released = np.array(_state()["q_rad"])
            time.sleep(0.5)
            assert np.max(np.abs(np.array(_state()["q_rad"]) - q_released)) < 1e-4
            term.keys("m", "m")  # base -> tool -> joint
            term.wait_for("mode: joint", 5)
            screens = term.hold(
                "t", until="stopped: wrist singularity", timeout_s=40
            )  # J5 + towards 0
            assert any(
                "slowing" in _status(s) and "wrist singularity" in _status(s) for s in screens
            )
            state = _state()
            assert state["safety_mode"] == "NORMAL"
            q5_deg = abs(np.degrees(state["q_rad"][4]))
            assert 8.0 <= q5_deg < 20.0, q5_deg
            term.keys("x")
            term.wait_for("EXIT=0", 15)
        finally:
            term.close()
