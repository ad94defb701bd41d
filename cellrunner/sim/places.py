"""Places judged in the twin (SPEC section 11): a part set down is compared with where the
task put it, never with how the gripper happened to hold it.

A task means to hold a part as a TCP at the part's frame holds it (SPEC: a part ``at:
FRAME`` sits where a TCP at FRAME grips it: centred between the jaws, or its top face
under the cups), so a place at ``T_world_tcp`` puts the part at ``T_world_tcp @
T_grip_part`` (:attr:`~.description.PartDescription.T_grip_part`), wherever it was picked
from: a part gripped off-centre (lying off its frame) is placed off its target by as
much, and judged so; a part picked where a camera saw it is held as meant.

:meth:`Places.inspect` measures the part released last where it rests: its distance and
angle from the target (an angle up to the shape's symmetries: a square box turned 90 deg
lies as well as before), what carries it (a fixture or another part; nothing: it is
still falling) and how fast it still moves (the engine waits for it to come to rest). A
part released a little above its support falls onto it: ``PLACE_DROP_M`` straight down
is not held against the verdict, but the offset reported is the whole distance.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

from cellrunner.model.geometry import Box, Cylinder, Shape, Sphere
from cellrunner.sim.mjcf_attrs import PADS, PARTS, STATIC

if TYPE_CHECKING:
    from cellrunner.sim.description import TwinDescription

PLACE_DROP_M = 0.01  # a part released this far above its support lands where it was put


@dataclass(frozen=True)
class PlaceInspection:
    """The part released last, measured where it rests against where the task put it.

    ``offset_m``: its distance from the target (the whole of it, a fall included);
    ``judged_m``: the same with up to ``PLACE_DROP_M`` of fall straight down forgiven
    (what the tolerance is held against); ``angle_deg``: its rotation from the target,
    up to the shape's symmetries; ``resting_on``: what carries it ("fixture", "part",
    "fixture and part"), None while nothing does (it is still falling or on the pads);
    ``speed_mps``: how fast it still moves."""

    part: str
    offset_m: float
    judged_m: float
    angle_deg: float
    resting_on: str | None
    speed_mps: float


class _Touches(Protocol):
    def kinds_touching(self, part: str) -> list[int]: ...


class PlaceWorld(Protocol):
    """What the place check reads of the twin (:class:`~cellrunner.sim.world.SimWorld`)."""

    description: TwinDescription

    @property
    def contacts(self) -> _Touches: ...

    def part_pose_world(self, name: str) -> np.ndarray: ...

    def part_velocity_world(self, name: str) -> np.ndarray: ...


class Places:
    """The place check of one built twin: the parts released last."""

    def __init__(self, world: PlaceWorld) -> None:
        self.world = world
        parts = world.description.parts
        #: part -> T_tcp_part of the grip the task means
        self.grip: dict[str, np.ndarray] = {p.name: np.array(p.T_grip_part) for p in parts}
        #: the parts released last
        self.released: frozenset[str] = frozenset()
        self._shapes: dict[str, Shape] = {p.name: p.shape for p in parts}
        self._symmetries: dict[str, list[np.ndarray]] = {}

    def let_go(self, names: frozenset[str] | set[str]) -> None:
        """The jaws opened on, or the cups released, ``names``."""
        if names:
            self.released = frozenset(names)

    def inspect(self, T_world_tcp: np.ndarray) -> PlaceInspection | None:
        """The part released last (the worst of them) against where a TCP at
        ``T_world_tcp`` puts it; None when no part was released."""
        worst: PlaceInspection | None = None
        for name in sorted(self.released):
            found = self._measure(name, T_world_tcp @ self.grip[name])
            if worst is None or found.judged_m > worst.judged_m:
                worst = found
        return worst

    def _measure(self, name: str, target: np.ndarray) -> PlaceInspection:
        actual = self.world.part_pose_world(name)
        d = actual[:3, 3] - target[:3, 3]
        drop = -float(d[2])
        fall_judged = max(0.0, drop - PLACE_DROP_M) if drop > 0 else -drop
        return PlaceInspection(
            name,
            float(np.linalg.norm(d)),
            math.hypot(float(d[0]), float(d[1]), fall_judged),
            self._angle_deg(name, target[:3, :3], actual[:3, :3]),
            self._support(name),
            float(np.linalg.norm(self.world.part_velocity_world(name))),
        )

    def _angle_deg(self, name: str, R_target: np.ndarray, R_actual: np.ndarray) -> float:
        shape = self._shapes[name]
        if isinstance(shape, Sphere):
            return 0.0
        if isinstance(shape, Cylinder):  # only its axis counts, either way up
            cos = abs(float(R_target[:, 2] @ R_actual[:, 2]))
            return math.degrees(math.acos(min(1.0, cos)))
        if name not in self._symmetries:
            self._symmetries[name] = _box_symmetries(shape)
        return min(_rotation_deg(R_target @ S, R_actual) for S in self._symmetries[name])

    def _support(self, name: str) -> str | None:
        kinds = self.world.contacts.kinds_touching(name)
        if any(k == PADS for k in kinds):
            return None  # still in the fingers or on the cups
        on = [label for bit, label in ((STATIC, "fixture"), (PARTS, "part")) if bit in kinds]
        return " and ".join(on) or None


def _rotation_deg(R_a: np.ndarray, R_b: np.ndarray) -> float:
    cos = (float(np.trace(R_a.T @ R_b)) - 1.0) / 2.0
    return math.degrees(math.acos(max(-1.0, min(1.0, cos))))


def _box_symmetries(shape: Shape) -> list[np.ndarray]:
    """The rotations that map a box onto itself (the identity alone for other shapes):
    half turns about its axes, and quarter turns where two sides are equal."""
    if not isinstance(shape, Box):
        return [np.eye(3)]
    size = np.asarray(shape.size_m, dtype=float)
    out = []
    for perm in itertools.permutations(range(3)):
        if not np.allclose(size[list(perm)], size, atol=1e-6):
            continue
        for signs in itertools.product((1.0, -1.0), repeat=3):
            S = np.zeros((3, 3))
            for row, col in enumerate(perm):
                S[row, col] = signs[row]
            if np.linalg.det(S) > 0:
                out.append(S)
    return out
