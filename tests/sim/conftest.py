"""Shared fixtures for the twin tests: the demo cell, a connected backend and a driver
that streams sealed quintic joint moves to it, one controller period at a time."""

from __future__ import annotations

import numpy as np
import pytest

from cellrunner.backends.sim.backend import SimBackend
from cellrunner.model.trajectory import approve
from cellrunner.sim import demo
from cellrunner.sim.description import TwinDescription, dh_forward
from cellrunner.sim.mujoco_loader import load_mujoco

# Import MuJoCo the package's way first (the root conftest chose its GL backend already).
load_mujoco()


class Driver:
    """Moves the demo robot through SimBackend like the engine does (servo, wait_period)."""

    def __init__(self, backend: SimBackend, description: TwinDescription):
        self.backend = backend
        self.desc = description
        self.q = np.array(description.q_home_rad)
        self.errors_m: list[float] = []

    def tcp_of(self, q: np.ndarray) -> np.ndarray:
        return (self.desc.T_world_base @ dh_forward(self.desc.spec, q) @ self.desc.T_flange_tcp)[
            :3, 3
        ]

    def move_joints(self, q_to: np.ndarray, duration_s: float, name: str = "move") -> float:
        """Stream a quintic to ``q_to``; returns the max TCP tracking error (m)."""
        rate = self.backend.rate_hz
        approved = approve(
            demo.to_trajectory(demo.quintic_blend(self.q, q_to, duration_s, rate), rate), 0, name
        )
        worst = 0.0
        for i, q_ref in enumerate(approved.trajectory.q_rad):
            self.backend.servo(approved, i)
            self.backend.wait_period()
            q_meas = self.backend.read_state().q_rad
            worst = max(worst, float(np.linalg.norm(self.tcp_of(q_meas) - self.tcp_of(q_ref))))
        self.q = np.array(q_to)
        self.errors_m.append(worst)
        return worst

    def move_tcp(self, xyz_m, duration_s: float, name: str = "move") -> float:
        q_to = demo.solve_ik(self.desc, demo.tcp_down_at(np.asarray(xyz_m, float)), self.q)
        return self.move_joints(q_to, duration_s, name)

    def wait(self, seconds: float) -> None:
        for _ in range(round(seconds * self.backend.rate_hz)):
            self.backend.wait_period()

    def pick_cube(self) -> None:
        """Approach, descend onto the cube and close the jaws (not lifted)."""
        grasp = np.array(demo.CUBE_XYZ_M) + (0, 0, 0.005)
        self.move_tcp(grasp + (0, 0, 0.10), 2.5, "approach")
        self.move_tcp(grasp, 1.0, "descend")
        self.backend.set_output("DO0", True)
        self.wait(0.6)


@pytest.fixture
def cell() -> TwinDescription:
    return demo.demo_description()


@pytest.fixture
def backend(cell: TwinDescription):
    b = SimBackend(cell)
    b.connect()
    yield b
    b.close()


@pytest.fixture
def driver(backend: SimBackend, cell: TwinDescription) -> Driver:
    return Driver(backend, cell)
