"""The twin's conveyor belts (SPEC section 13): a belt that carries its parts by friction.

Each straight conveyor of the cell is a thin slab riding a slide joint along its path,
driven at the belt's speed by a velocity servo; parts are free bodies resting on it, so
they travel because the slab drags them (a part held still by the jaws slips on it, as
on a real belt). A slab cannot run for ever: it is longer than the path by
``2 * WRAP_M`` and jumps back by ``WRAP_M`` each time it has travelled that far. Its top
face is continuous under the path before and after the jump and its speed is unchanged,
so a part resting on it feels nothing. The belt's travel since the twin started is the
encoder (:meth:`Belts.travel_m`), counted in ticks as a pulse decoder counts them.

The photo-eye is a presence sensor on the path (:func:`eye_sensor`): its input reads true
once a part's centre has passed the eye (for ``2 * EYE_HALF_WIDTH_M`` along the path).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.sim.mjcf_attrs import PARTS, STATIC, fmt

if TYPE_CHECKING:
    from cellrunner.model.conveyor import Conveyor
    from cellrunner.sim.description import PresenceSensor

#: the slab jumps back by this much after travelling it, m
WRAP_M = 1.0
#: the slab's thickness, m; its top lies ``LIFT_M`` above the path (over any fixture there)
THICKNESS_M = 0.01
LIFT_M = 0.002
#: the slab's mass (kg) and its velocity servo's gain (N s/m): stiff against a part's drag
MASS_KG = 50.0
SERVO_KV = 20000.0
#: the eye's beam: a part's centre from the eye to twice this downstream of it, m (the
#: beam rises within a period's travel after the centre passed the eye)
EYE_HALF_WIDTH_M = 0.001
#: how wide the slab is, m
WIDTH_M = 0.2


@dataclass(frozen=True)
class BeltDescription:
    """A straight belt: its path ``start_m`` -> ``end_m`` (world, m), its speed (m/s) and
    the encoder's ticks per m (None: an exact reading)."""

    name: str
    start_m: tuple[float, float, float]
    end_m: tuple[float, float, float]
    speed_mps: float
    ticks_per_m: float | None = None
    #: the controller's pulse decoder this belt's encoder is wired to (``source: ur``)
    encoder_index: int | None = None

    @property
    def direction(self) -> np.ndarray:
        d = np.subtract(self.end_m, self.start_m)
        out: np.ndarray = d / np.linalg.norm(d)
        return out

    @property
    def length_m(self) -> float:
        return float(math.dist(self.start_m, self.end_m))


def belt_of(name: str, conveyor: Conveyor) -> BeltDescription | None:
    """The twin's belt of a cell's conveyor; None for a round table (not built in the
    twin). It runs at the encoder's constant speed, else at ``speed_max``."""
    line = conveyor.path.line
    if line is None:
        return None
    enc = conveyor.encoder
    speed = float(enc.mps) if enc.source == "speed" and enc.mps is not None else None
    ticks = float(enc.ticks_per_m) if enc.ticks_per_m is not None else None
    return BeltDescription(
        name,
        tuple(float(v) for v in line.from_),  # type: ignore[arg-type]
        tuple(float(v) for v in line.to),  # type: ignore[arg-type]
        speed if speed is not None else float(conveyor.speed_max),
        ticks,
        enc.index if enc.source == "ur" else None,
    )


def eye_sensor(belt: BeltDescription, channel: str, eye_s_m: float) -> PresenceSensor:
    """The photo-eye ``eye_s_m`` along the belt as a light barrier on input ``channel``:
    thin along the path, as wide as the slab across it."""
    from cellrunner.sim.description import PresenceSensor

    # the beam reads a part from the moment its centre passes the eye: a box from the eye
    # to 2 half widths downstream
    p = np.asarray(belt.start_m) + belt.direction * (eye_s_m + EYE_HALF_WIDTH_M)
    along = np.abs(belt.direction)
    half = np.where(along > 0.5, EYE_HALF_WIDTH_M, WIDTH_M / 2)
    half[2] = 0.2
    return PresenceSensor(channel, (float(p[0]), float(p[1]), float(p[2])), tuple(half.tolist()))


def add_belts(world: ET.Element, actuators: ET.Element, belts: tuple[BeltDescription, ...]) -> None:
    """The slabs (bodies ``belt:<name>``, slide joints and velocity servos of that name)."""
    for belt in belts:
        d = belt.direction
        # the slab's frame: x along the path, centred on the path's middle
        x = d
        y = np.cross([0.0, 0.0, 1.0], x)
        y = y / np.linalg.norm(y) if np.linalg.norm(y) > 1e-9 else np.array([0.0, 1.0, 0.0])
        z = np.cross(x, y)
        R = np.column_stack([x, y, z])
        from cellrunner.sim.mjcf_attrs import quat_of

        centre = (np.asarray(belt.start_m) + np.asarray(belt.end_m)) / 2
        centre = centre + np.array([0.0, 0.0, LIFT_M - THICKNESS_M / 2])
        body = ET.SubElement(
            world, "body", name=f"belt:{belt.name}", pos=fmt(centre), quat=fmt(quat_of(R))
        )
        ET.SubElement(body, "joint", name=f"belt:{belt.name}", type="slide", axis="1 0 0")
        half_len = belt.length_m / 2 + 2 * WRAP_M
        ET.SubElement(
            body,
            "geom",
            name=f"belt:{belt.name}",
            type="box",
            size=fmt([half_len, WIDTH_M / 2, THICKNESS_M / 2]),
            mass=f"{MASS_KG:g}",
            friction="1.0 0.01 0.0001",
            rgba="0.15 0.15 0.15 1",
            contype=str(STATIC),
            conaffinity=str(PARTS),
        )
        ET.SubElement(
            actuators,
            "velocity",
            name=f"belt:{belt.name}",
            joint=f"belt:{belt.name}",
            kv=f"{SERVO_KV:g}",
        )


class Belts:
    """The belts of one built twin: their speeds, the jump back, the encoders."""

    def __init__(self, model: Any, data: Any, belts: tuple[BeltDescription, ...]) -> None:
        self.data = data
        self.descs = {b.name: b for b in belts}
        self.speed_mps = {b.name: b.speed_mps for b in belts}
        self._qpos = {
            b.name: int(model.jnt_qposadr[model.joint(f"belt:{b.name}").id]) for b in belts
        }
        self._ctrl = {b.name: int(model.actuator(f"belt:{b.name}").id) for b in belts}
        self._wrapped_m = dict.fromkeys(self.descs, 0.0)
        for name in self.descs:
            data.ctrl[self._ctrl[name]] = self.speed_mps[name]

    def set_speed(self, name: str, speed_mps: float) -> None:
        """Run belt ``name`` at ``speed_mps`` from the next physics step (0: it stops)."""
        self.speed_mps[name] = float(speed_mps)
        self.data.ctrl[self._ctrl[name]] = float(speed_mps)

    def jump_encoder(self, name: str, distance_m: float) -> None:
        """An encoder fault: belt ``name``'s reading jumps by ``distance_m`` (the belt
        itself runs on as it did)."""
        self._wrapped_m[name] += float(distance_m)

    def update(self) -> None:
        """After a period: a slab that has travelled ``WRAP_M`` jumps back by it."""
        for name, adr in self._qpos.items():
            if self.data.qpos[adr] >= WRAP_M:
                self.data.qpos[adr] -= WRAP_M
                self._wrapped_m[name] += WRAP_M

    def travel_m(self, name: str) -> float:
        """The belt's travel since the twin started, m, as its encoder reads it (whole
        ticks)."""
        exact = self._wrapped_m[name] + float(self.data.qpos[self._qpos[name]])
        ticks = self.descs[name].ticks_per_m
        return exact if ticks is None else math.floor(exact * ticks) / ticks

    def encoder_ticks(self, index: int) -> int | None:
        """The whole ticks the encoder wired to the controller's pulse decoder ``index``
        has given since the twin started (its belt's travel x ticks_per_m); None when no
        belt's encoder is wired there."""
        for name, desc in self.descs.items():
            if desc.encoder_index == index and desc.ticks_per_m is not None:
                exact = self._wrapped_m[name] + float(self.data.qpos[self._qpos[name]])
                return math.floor(exact * desc.ticks_per_m)
        return None


#: a part the rehearsal puts on a belt lies this far upstream of the eye, m (at most: never
#: off the path's start)
FEED_LEAD_M = 0.25
#: a part within this of a conveyor's frame is one that belt brings, m
AT_FRAME_M = 0.05


def belts_of_cell(
    conveyors: dict[str, Conveyor], inputs: dict[str, str], frames: dict[str, np.ndarray]
) -> tuple[tuple[BeltDescription, ...], tuple[PresenceSensor, ...], dict[str, np.ndarray]]:
    """The twin's belts of a cell's straight conveyors, their photo-eyes (on the channel
    of each trigger input), and for each the shift (4x4, world) that moves a part lying
    at the conveyor's frame to where the rehearsal puts it: ``FEED_LEAD_M`` upstream of
    the eye, resting on the slab. ``frames``: each conveyor's frame pose (world)."""
    from cellrunner.model.conveyor import T_world_shift, s_of_point_m

    belts, eyes, shifts = [], [], {}
    for name, conveyor in conveyors.items():
        belt = belt_of(name, conveyor)
        if belt is None:
            continue
        s_frame, _ = s_of_point_m(conveyor.path, frames[name][:3, 3].tolist())
        s_eye = s_frame - float(conveyor.eye_to_frame)
        belts.append(belt)
        eyes.append(eye_sensor(belt, inputs[conveyor.trigger.input], s_eye))
        lead = min(FEED_LEAD_M, max(0.0, s_eye - 0.05))
        shift = T_world_shift(conveyor.path, -(float(conveyor.eye_to_frame) + lead))
        shift[2, 3] += LIFT_M
        shifts[name] = shift
    return tuple(belts), tuple(eyes), shifts


def upstream(
    T_world_part: np.ndarray, frames: dict[str, np.ndarray], shifts: dict[str, np.ndarray]
) -> np.ndarray:
    """``T_world_part`` moved upstream of its belt's eye when it lies at a belt's frame
    (see :func:`belts_of_cell`), else as it is."""
    for name, shift in shifts.items():
        if np.linalg.norm(T_world_part[:3, 3] - frames[name][:3, 3]) <= AT_FRAME_M:
            out: np.ndarray = shift @ T_world_part
            return out
    return T_world_part
