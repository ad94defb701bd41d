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
    #: a round table: ``(centre (world, m), radius m, from rad, +1 ccw / -1 cw)``; then the
    #: belt is a disc turning about the centre (``start_m``/``end_m`` are the arc's ends)
    arc: tuple[tuple[float, float, float], float, float, float] | None = None

    @property
    def direction(self) -> np.ndarray:
        """The direction parts travel at the path's start (world, unit)."""
        return self.tangent_at(0.0)

    def point_at(self, s_m: float) -> np.ndarray:
        """The path's point ``s_m`` along it (world, m)."""
        if self.arc is None:
            out: np.ndarray = np.asarray(self.start_m) + self.tangent_at(0.0) * s_m
            return out
        centre, radius, a0, sign = self.arc
        a = a0 + sign * s_m / radius
        return np.asarray(centre) + radius * np.array([math.cos(a), math.sin(a), 0.0])

    def tangent_at(self, s_m: float) -> np.ndarray:
        """The direction parts travel ``s_m`` along the path (world, unit)."""
        if self.arc is None:
            d = np.subtract(self.end_m, self.start_m)
            line: np.ndarray = d / np.linalg.norm(d)
            return line
        _, radius, a0, sign = self.arc
        a = a0 + sign * s_m / radius
        return sign * np.array([-math.sin(a), math.cos(a), 0.0])

    @property
    def length_m(self) -> float:
        return float(math.dist(self.start_m, self.end_m))


def belt_of(name: str, conveyor: Conveyor) -> BeltDescription:
    """The twin's belt of a cell's conveyor, a slab for a line, a disc for a round table.
    It runs at the encoder's constant speed, else at ``speed_max``."""
    enc = conveyor.encoder
    speed = float(enc.mps) if enc.source == "speed" and enc.mps is not None else None
    ticks = float(enc.ticks_per_m) if enc.ticks_per_m is not None else None
    index = enc.index if enc.source == "ur" else None
    speed_mps = speed if speed is not None else float(conveyor.speed_max)
    line = conveyor.path.line
    if line is not None:
        return BeltDescription(
            name,
            tuple(float(v) for v in line.from_),  # type: ignore[arg-type]
            tuple(float(v) for v in line.to),  # type: ignore[arg-type]
            speed_mps,
            ticks,
            index,
        )
    arc = conveyor.path.arc
    assert arc is not None
    centre = (float(arc.centre[0]), float(arc.centre[1]), float(arc.centre[2]))
    a0, a1 = math.radians(float(arc.from_deg)), math.radians(float(arc.to_deg))
    ends = [
        (centre[0] + arc.radius * math.cos(a), centre[1] + arc.radius * math.sin(a), centre[2])
        for a in (a0, a1)
    ]
    return BeltDescription(
        name,
        ends[0],
        ends[1],
        speed_mps,
        ticks,
        index,
        (centre, float(arc.radius), a0, 1.0 if a1 > a0 else -1.0),
    )


def eye_sensor(belt: BeltDescription, channel: str, eye_s_m: float) -> PresenceSensor:
    """The photo-eye ``eye_s_m`` along the belt as a light barrier on input ``channel``:
    thin along the path, as wide as the slab across it."""
    from cellrunner.sim.description import PresenceSensor

    # the beam reads a part from the moment its centre passes the eye: a box from the eye
    # to 2 half widths downstream
    p = belt.point_at(eye_s_m + EYE_HALF_WIDTH_M)
    along = np.abs(belt.tangent_at(eye_s_m))
    half = np.where(along > 0.5, EYE_HALF_WIDTH_M, WIDTH_M / 2)
    half[2] = 0.2
    return PresenceSensor(channel, (float(p[0]), float(p[1]), float(p[2])), tuple(half.tolist()))


def add_belts(world: ET.Element, actuators: ET.Element, belts: tuple[BeltDescription, ...]) -> None:
    """The slabs (bodies ``belt:<name>``, slide joints and velocity servos of that name)."""
    for belt in belts:
        if belt.arc is not None:
            _add_disc(world, actuators, belt)
            continue
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
        size = [half_len, WIDTH_M / 2, THICKNESS_M / 2]
        _add_surface(body, actuators, belt.name, "box", size, SERVO_KV)


def _add_disc(world: ET.Element, actuators: ET.Element, belt: BeltDescription) -> None:
    """A round table: a disc (body ``belt:<name>``) on a hinge about the arc's centre
    (world Z, turned the way the arc runs), its top ``LIFT_M`` above the path, as wide as
    the slab around the parts' circle, driven by a velocity servo (rad/s)."""
    assert belt.arc is not None
    centre, radius, _, sign = belt.arc
    pos = np.asarray(centre) + np.array([0.0, 0.0, LIFT_M - THICKNESS_M / 2])
    body = ET.SubElement(world, "body", name=f"belt:{belt.name}", pos=fmt(pos))
    axis = "0 0 1" if sign > 0 else "0 0 -1"
    ET.SubElement(body, "joint", name=f"belt:{belt.name}", type="hinge", axis=axis)
    size = [radius + WIDTH_M / 2, THICKNESS_M / 2]
    # the servo's gain in rad/s: the slab's stiffness at the parts' radius
    _add_surface(body, actuators, belt.name, "cylinder", size, SERVO_KV * radius**2)


def _add_surface(
    body: ET.Element,
    actuators: ET.Element,
    name: str,
    shape: str,
    size: list[float],
    kv: float,
) -> None:
    """What carries the parts on a belt's body: its surface (``shape`` of ``size``, the
    friction parts ride on) and the velocity servo on its joint (gain ``kv``)."""
    ET.SubElement(
        body,
        "geom",
        name=f"belt:{name}",
        type=shape,
        size=fmt(size),
        mass=f"{MASS_KG:g}",
        friction="1.0 0.01 0.0001",
        rgba="0.15 0.15 0.15 1",
        contype=str(STATIC),
        conaffinity=str(PARTS),
    )
    ET.SubElement(actuators, "velocity", name=f"belt:{name}", joint=f"belt:{name}", kv=f"{kv:g}")


class Belts:
    """The belts of one built twin: their speeds, the jump back, the encoders."""

    def __init__(
        self, model: Any, data: Any, belts: tuple[BeltDescription, ...], period_s: float
    ) -> None:
        self.data = data
        self.period_s = float(period_s)
        self.descs = {b.name: b for b in belts}
        self.speed_mps = {b.name: b.speed_mps for b in belts}
        #: a speed change under way: belt -> (the speed it goes to, m/s; its ramp, m/s^2)
        self._ramps: dict[str, tuple[float, float]] = {}
        self._qpos = {
            b.name: int(model.jnt_qposadr[model.joint(f"belt:{b.name}").id]) for b in belts
        }
        self._ctrl = {b.name: int(model.actuator(f"belt:{b.name}").id) for b in belts}
        self._wrapped_m = dict.fromkeys(self.descs, 0.0)
        #: m of travel per unit of the joint: 1 for a slab, the radius for a disc (rad)
        self._m_per_q = {b.name: b.arc[1] if b.arc is not None else 1.0 for b in belts}
        for name in self.descs:
            data.ctrl[self._ctrl[name]] = self.speed_mps[name] / self._m_per_q[name]

    def set_speed(self, name: str, speed_mps: float, ramp_mps2: float | None = None) -> None:
        """Run belt ``name`` at ``speed_mps`` (0: it stops): from the next physics step,
        or, with ``ramp_mps2``, changing its speed by that much a second as a drive's
        ramp does (a line's motor does not stop a loaded belt at once)."""
        self._ramps.pop(name, None)
        if ramp_mps2 is not None and ramp_mps2 > 0:
            self._ramps[name] = (float(speed_mps), float(ramp_mps2))
            return
        self._command(name, float(speed_mps))

    def _command(self, name: str, speed_mps: float) -> None:
        self.speed_mps[name] = speed_mps
        self.data.ctrl[self._ctrl[name]] = speed_mps / self._m_per_q[name]

    def jump_encoder(self, name: str, distance_m: float) -> None:
        """An encoder fault: belt ``name``'s reading jumps by ``distance_m`` (the belt
        itself runs on as it did)."""
        self._wrapped_m[name] += float(distance_m)

    def update(self) -> None:
        """After a period: a ramping belt's speed one period on; a slab that has
        travelled ``WRAP_M`` jumps back by it."""
        for name, (target, ramp) in list(self._ramps.items()):
            now = self.speed_mps[name]
            step = ramp * self.period_s
            self._command(
                name,
                target if abs(target - now) <= step else now + math.copysign(step, target - now),
            )
            if self.speed_mps[name] == target:
                del self._ramps[name]
        for name, adr in self._qpos.items():
            if self.descs[name].arc is None and self.data.qpos[adr] >= WRAP_M:
                self.data.qpos[adr] -= WRAP_M
                self._wrapped_m[name] += WRAP_M

    def _q_m(self, name: str) -> float:
        """The joint's travel along the parts' path, m."""
        return float(self.data.qpos[self._qpos[name]]) * self._m_per_q[name]

    def travel_m(self, name: str) -> float:
        """The belt's travel since the twin started, m, as its encoder reads it (whole
        ticks)."""
        exact = self._wrapped_m[name] + self._q_m(name)
        ticks = self.descs[name].ticks_per_m
        return exact if ticks is None else math.floor(exact * ticks) / ticks

    def encoder_ticks(self, index: int) -> int | None:
        """The whole ticks the encoder wired to the controller's pulse decoder ``index``
        has given since the twin started (its belt's travel x ticks_per_m); None when no
        belt's encoder is wired there."""
        for name, desc in self.descs.items():
            if desc.encoder_index == index and desc.ticks_per_m is not None:
                exact = self._wrapped_m[name] + self._q_m(name)
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
    """The twin's belts of a cell's conveyors (slabs and discs), their photo-eyes (on the channel
    of each trigger input), and for each the shift (4x4, world) that moves a part lying
    at the conveyor's frame to where the rehearsal puts it: ``FEED_LEAD_M`` upstream of
    the eye, resting on the slab. ``frames``: each conveyor's frame pose (world)."""
    from cellrunner.model.conveyor import T_world_shift, s_of_point_m

    belts, eyes, shifts = [], [], {}
    for name, conveyor in conveyors.items():
        belt = belt_of(name, conveyor)
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
