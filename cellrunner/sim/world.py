"""The physics twin of one cell: MuJoCo model and data, stepped one controller period at
a time, with the controller's behaviour around it (servo set-point, safety state, stop
ramps), the IO image and physical fault injection.

``SimWorld`` knows nothing about trajectories or the engine; :mod:`.backend` wraps it in
the :class:`~cellrunner.backends.base.RobotBackend` Protocol. Everything the engine can
learn comes out of :meth:`SimWorld.measure` (a RobotState: joints, wrist wrench, IO, safety):
fault injections change the physics, never a flag the engine could read.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Set
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cellrunner.backends.base import BackendError, RobotState, Safety
from cellrunner.model.robots import JOINT_NAMES
from cellrunner.sim.description import TwinDescription
from cellrunner.sim.input_rules import InputRules
from cellrunner.sim.mjcf import PhysicsOptions, compile_model
from cellrunner.sim.mjcf_attrs import PADS, PARTS, ROBOT, STATIC, TOOL
from cellrunner.sim.mujoco_loader import load_mujoco

UNLOCK_DELAY_S = 5.0  # UR: a protective stop can be unlocked 5 s after it happened
STOP_DECEL_RAD_S2 = 30.0  # category 2 stop ramp (protective stop, stopJ default)
GRAVITY_MPS2 = 9.81
JAW_REST_SPEED_MPS = 0.005
COLLISION_BACKOFF_S = 0.02
SLIP_HOLD_FRACTION = 0.25  # a slipping grip holds only this fraction of the part's weight
AIR_CLEARANCE_M = 0.01  # "in the air": this far from every fixture and the floor
PLACE_DROP_M = 0.01  # a part released this far above its support lands where it was put
JAM_SLIDE_M = 0.005  # a gripped part forced back this far in the jaws by a fixture: a collision
JAM_FORCE_N = 150.0  # or pressed onto a fixture this hard (UR's default force limit)
GRAVITY_M_S2 = 9.81


class Fault(enum.StrEnum):
    """Faults the twin can make physically happen (SPEC section 5, robot side)."""

    GRIP_MISS = "grip_miss"  # the part is moved away when the jaws start to close
    PART_SLIP = "part_slip"  # a gripped part loses its grip once in the air, and falls
    PROTECTIVE_STOP = "protective_stop"
    ESTOP = "estop"
    ROBOT_DISCONNECT = "robot_disconnect"  # handled by the backend (connection lost)

    @classmethod
    def parse(cls, name: str | Fault) -> Fault:
        try:
            return cls(name)
        except ValueError:
            known = ", ".join(f.value for f in cls)
            raise ValueError(f"unknown fault {name!r}; known: {known}") from None


class StopReason(enum.StrEnum):
    CONTACT = "contact"
    INJECTED = "injected"
    REQUESTED = "requested"


@dataclass
class _Stop:
    """A synchronized linear velocity ramp to standstill from ``qd0_rad_s``."""

    t0_s: float
    qd0_rad_s: np.ndarray
    duration_s: float

    def speed(self, t_s: float) -> np.ndarray:
        s = max(0.0, 1.0 - (t_s - self.t0_s) / self.duration_s) if self.duration_s > 0 else 0.0
        return self.qd0_rad_s * s


@dataclass
class ContactEvent:
    """The unexpected contact that raised a protective stop (for logs and reports)."""

    time_s: float
    force_N: float
    geoms: tuple[str, str]


@dataclass
class _Ids:
    qpos: np.ndarray
    dof: np.ndarray
    servo: np.ndarray
    ff_gain: np.ndarray  # kv/kp per arm servo
    jaw_qpos: np.ndarray
    jaw_dof: np.ndarray
    jaw_act: np.ndarray
    pad_geoms: tuple[int, int]
    pad_friction: np.ndarray
    part_bodies: dict[str, int]
    part_qpos: dict[str, int]
    part_geom: dict[str, int]
    part_friction: dict[str, np.ndarray]
    geom_kind: np.ndarray  # STATIC / ROBOT / PADS / PARTS per geom, 0 for none
    tool_body: int
    ft_site: int
    tcp_site: int
    force_adr: int
    torque_adr: int
    tool_mass_kg: float


@dataclass
class _Faults:
    grip_miss_armed: bool = False
    slip_armed: bool = False
    slipping: set[str] = field(default_factory=set)


class SimWorld:
    """The twin: construct with a description, ``build()``, then ``step_period()``."""

    def __init__(self, description: TwinDescription, options: PhysicsOptions | None = None) -> None:
        self.description = description
        self.options = options if options is not None else PhysicsOptions()
        self._rate_hz = description.rate_hz
        self.period_s = 1.0 / self._rate_hz
        self.substeps = max(1, math.ceil(self.period_s / self.options.max_timestep_s - 1e-9))
        self.model: Any = None
        self.data: Any = None
        self._mj: Any = None
        self._ids: _Ids | None = None

    @property
    def ids(self) -> _Ids:
        """The built model's indices (joints, parts, pads, sites)."""
        if self._ids is None:
            raise RuntimeError("the twin's model is not built yet; call build() first")
        return self._ids

    # -- lifecycle ----------------------------------------------------------------------
    def build(self) -> None:
        """Compile the model and put the arm at home and the parts at their frames."""
        self._mj = load_mujoco()
        self.model = compile_model(self.description, self.options)
        self.data = self._mj.MjData(self.model)
        self._ids = self._lookup_ids()
        self._periods = 0
        ids = self.ids
        self.data.qpos[ids.qpos] = self.description.q_home_rad
        self._mj.mj_forward(self.model, self.data)
        self.q_ref = np.array(self.description.q_home_rad, dtype=float)
        self.qd_ref = np.zeros(6)
        self.safety = Safety.NORMAL
        self.powered = True
        self.estop_pressed = False
        self.stop_time_s: float | None = None
        self.last_contact: ContactEvent | None = None
        self._stop: _Stop | None = None
        self._faults = _Faults()
        d = self.description
        self.outputs: dict[str, float | bool] = {c: _zero(c) for c in d.io_outputs}
        self.inputs: dict[str, float | bool] = {c: _zero(c) for c in d.io_inputs}
        self._scripted_inputs: dict[str, float | bool] = {}
        self._rules = InputRules(d.input_rules) if d.input_rules else None
        self._held_at: dict[
            str, np.ndarray
        ] = {}  # gripped part -> T_tcp_part while no fixture presses it
        self._held_last: dict[str, np.ndarray] = {}  # the same, of the parts released last
        self._closing = False
        self._jaws_driven = False  # jaw forces not written to ctrl yet
        self._ft_offset: tuple[float, ...] = (0.0,) * 6
        self._kind = [int(k) for k in ids.geom_kind]
        # Hot-path views into MjData (its buffers never move). The arm's joints and
        # servos come first in the model, so they are plain slices.
        assert list(ids.qpos) == list(range(6)) and list(ids.dof) == list(range(6))
        assert list(ids.servo) == list(range(6))
        self._qpos, self._qvel = self.data.qpos, self.data.qvel
        self._q_view = self.data.qpos[0:6]
        self._qd_view = self.data.qvel[0:6]
        self._servo_ctrl = self.data.ctrl[0:6]
        self._ctrl_tmp = np.zeros(6)
        self._R_site_flat = self.data.site_xmat[ids.ft_site]  # row-major 3x3
        self._ft_flat = self.data.sensordata[ids.force_adr : ids.force_adr + 6]  # force, torque
        self._tool_com = self.data.subtree_com[ids.tool_body]
        self._site_pos = self.data.site_xpos[ids.ft_site]
        self._pad_a = ids.pad_geoms[0]
        self._part_of_geom = {g: name for name, g in ids.part_geom.items()}
        self._part_mass_kg = {p.name: p.mass_kg for p in self.description.parts}
        self._force6 = np.zeros(6)
        self._fromto6 = np.zeros(6)
        self._static_geoms = [g for g, k in enumerate(self._kind) if k == STATIC]
        self._robot_or_pad_geoms = frozenset(
            g for g, k in enumerate(self._kind) if k & (ROBOT | PADS | TOOL)
        )
        # The arm settles one physics step ahead of its servo input (measured), hence -h.
        self._ff_lead = ids.ff_gain - self.period_s / self.substeps
        self._q_prev_ref = self.q_ref.copy()
        self._qd_prev_ref: np.ndarray = _ZERO6
        self._hermite = _hermite_table(self.substeps, self.period_s)
        R_world_base = np.array(self.description.T_world_base[:3, :3], dtype=float)
        self._R_base_world_flat = tuple(R_world_base.T.ravel().tolist())
        self._tool_weight_N = GRAVITY_MPS2 * ids.tool_mass_kg
        self._gripped: frozenset[str] = _NONE
        self._vac_geoms: frozenset[int] = frozenset()  # part geoms the cups hold
        # geom pairs of the last contact check that found nothing suspicious, and its
        # verdict (the gripped parts)
        self._clean_pairs: list[list[int]] | None = None
        self._clean_gripped: frozenset[str] = _NONE
        self._jaw_adr = [int(a) for a in ids.jaw_qpos]
        self._jaw_dof = [int(a) for a in ids.jaw_dof]
        self._jaw_act = [int(a) for a in ids.jaw_act]
        self.data.ctrl[ids.servo] = self.q_ref
        self._mj.mj_forward(self.model, self.data)
        self.vacuum = None
        self.jaws_enabled = True
        if self.description.vacuum is not None:
            from cellrunner.sim.vacuum import VacuumCups

            self.vacuum = VacuumCups(self, self.description.vacuum)
        self.changer = None
        if self.description.tool_changer is not None:
            from cellrunner.sim.tool_changer import ToolChanger

            self.changer = ToolChanger(self, self.description.tool_changer)
        self._update_inputs()

    @property
    def built(self) -> bool:
        return self.data is not None

    @property
    def time_s(self) -> float:
        """Simulated time (s), counted in whole controller periods (no float drift)."""
        return self._periods / self._rate_hz

    def _lookup_ids(self) -> _Ids:
        m, _mj, d = self.model, self._mj, self.description
        joints = [m.joint(n).id for n in JOINT_NAMES]
        servo = np.array([m.actuator(f"servo:{n}").id for n in JOINT_NAMES])
        kp = m.actuator_gainprm[servo, 0]
        kv = -m.actuator_biasprm[servo, 2]
        geom_kind = np.zeros(m.ngeom, dtype=int)
        for g in range(m.ngeom):
            if m.geom_contype[g] or m.geom_conaffinity[g]:
                geom_kind[g] = m.geom_contype[g]
        gripper = d.gripper is not None
        jaws = [m.joint(j).id for j in ("jaw_a", "jaw_b")] if gripper else []
        pads = (m.geom("pad:jaw_a").id, m.geom("pad:jaw_b").id) if gripper else (-1, -1)
        tool = m.body("tool").id
        return _Ids(
            qpos=m.jnt_qposadr[joints].copy(),
            dof=m.jnt_dofadr[joints].copy(),
            servo=servo,
            ff_gain=kv / kp,
            jaw_qpos=m.jnt_qposadr[jaws].copy() if gripper else np.zeros(0, int),
            jaw_dof=m.jnt_dofadr[jaws].copy() if gripper else np.zeros(0, int),
            jaw_act=np.array(
                [m.actuator(f"drive:{j}").id for j in ("jaw_a", "jaw_b")] if gripper else [],
                dtype=int,
            ),
            pad_geoms=pads,
            pad_friction=m.geom_friction[list(pads)].copy() if gripper else np.zeros((0, 3)),
            part_bodies={p.name: m.body(f"part:{p.name}").id for p in d.parts},
            part_qpos={p.name: int(m.jnt_qposadr[m.joint(f"part:{p.name}").id]) for p in d.parts},
            part_geom={p.name: m.geom(f"part:{p.name}").id for p in d.parts},
            part_friction={
                p.name: m.geom_friction[m.geom(f"part:{p.name}").id].copy() for p in d.parts
            },
            geom_kind=geom_kind,
            tool_body=tool,
            ft_site=m.site("ft").id,
            tcp_site=m.site("tcp").id,
            force_adr=int(m.sensor_adr[m.sensor("ft_force").id]),
            torque_adr=int(m.sensor_adr[m.sensor("ft_torque").id]),  # == force_adr + 3
            tool_mass_kg=float(m.body_subtreemass[tool]),
        )

    # -- commands -----------------------------------------------------------------------
    def command(self, q_ref_rad: np.ndarray, qd_ref_rad_s: np.ndarray) -> None:
        """Set the servo set-point for the next period (servoJ)."""
        self.check_can_move()
        # never modified in place (every update rebinds), so no copies are needed
        self.q_ref = q_ref_rad
        self.qd_ref = qd_ref_rad_s

    def place_arm(self, q_rad: np.ndarray) -> None:
        """Put the arm at ``q_rad`` standing still, the servo set-point there (a controller
        that starts, or resets its model, with the arm at ``q_rad``)."""
        assert self._ids is not None, "build() first"
        q = np.array(q_rad, dtype=float)
        self.data.qpos[self._ids.qpos] = q
        self.data.qvel[self._ids.dof] = 0.0
        self.q_ref = self._q_prev_ref = q.copy()
        self.qd_ref = self._qd_prev_ref = _ZERO6
        self._mj.mj_forward(self.model, self.data)

    @property
    def stopping(self) -> bool:
        """Whether a stop ramp (stopJ, a protective or emergency stop) is still running."""
        return self._stop is not None

    def check_can_move(self) -> None:
        """Raise BackendError unless the controller would accept motion commands now."""
        if self.safety is not Safety.NORMAL:
            raise BackendError(f"robot cannot move: safety state is {self.safety.value}")
        if self.stopping:
            raise BackendError("robot is stopping (stopJ); wait until it stands still")

    def stop_motion(self, decel_rad_s2: float = STOP_DECEL_RAD_S2) -> None:
        """Ramp the set-point to standstill, along the current commanded motion."""
        self._begin_stop(decel_rad_s2)

    def set_output(self, channel: str, value: bool | float) -> None:
        if channel not in self.outputs:
            raise BackendError(f"unknown output {channel!r}; known: {', '.join(self.outputs)}")
        self.outputs[channel] = value

    def set_input(self, channel: str, value: bool | float) -> None:
        """Drive an input that no twin sensor drives (a test or a scripted peer)."""
        if channel not in self.inputs:
            raise BackendError(f"unknown input {channel!r}; known: {', '.join(self.inputs)}")
        if channel in self._sensor_channels():
            raise BackendError(f"input {channel!r} is driven by a twin sensor")
        self._scripted_inputs[channel] = value
        self.inputs[channel] = value

    def zero_ft_sensor(self) -> None:
        self._ft_offset = tuple(self._raw_wrench_base())

    def unlock_protective_stop(self) -> None:
        if self.safety is Safety.NORMAL:
            return
        if self.safety is not Safety.PROTECTIVE_STOP:
            raise BackendError(f"cannot unlock a protective stop in state {self.safety.value}")
        assert self.stop_time_s is not None
        elapsed = self.time_s - self.stop_time_s
        if elapsed < UNLOCK_DELAY_S:
            raise BackendError(
                f"protective stop cannot be unlocked yet: {elapsed:.2f} s since the stop, "
                f"the controller needs {UNLOCK_DELAY_S:.0f} s"
            )
        self._resume()

    def press_estop(self) -> None:
        """A person presses the emergency stop: category 1 stop, then power off."""
        self.estop_pressed = True
        if self.safety is not Safety.EMERGENCY_STOP:
            self.safety = Safety.EMERGENCY_STOP
            self.stop_time_s = self.time_s
            self._begin_stop(STOP_DECEL_RAD_S2)

    def release_estop(self) -> None:
        """A person twists the e-stop button out; the robot stays off until recovered."""
        self.estop_pressed = False

    def recover_from_estop(self) -> None:
        if self.safety is not Safety.EMERGENCY_STOP:
            return
        if self.estop_pressed:
            raise BackendError("emergency stop is still pressed; a person must release it first")
        self.powered = True
        self._resume()

    def raise_protective_stop(self, reason: StopReason = StopReason.INJECTED) -> None:
        if self.safety is not Safety.NORMAL:
            return
        self.safety = Safety.PROTECTIVE_STOP
        self.stop_time_s = self.time_s
        if reason is StopReason.CONTACT:
            # A collision: hold where the arm was just before (backing off 20 ms of the
            # motion, as UR arms back off) rather than ramp on into the obstacle.
            self._stop = None
            q, qd = self.data.qpos[self.ids.qpos], self.data.qvel[self.ids.dof]
            self.q_ref = self._q_prev_ref = q - COLLISION_BACKOFF_S * qd
            self.qd_ref = self._qd_prev_ref = _ZERO6
        else:
            self._begin_stop(STOP_DECEL_RAD_S2)

    def inject_fault(self, fault: str | Fault) -> None:
        """Make ``fault`` happen physically (see :class:`Fault`); robot_disconnect is the
        backend's business."""
        f = Fault.parse(fault)
        if f in (Fault.GRIP_MISS, Fault.PART_SLIP) and self.vacuum is not None:
            setattr(self.vacuum, "grip_miss_armed" if f is Fault.GRIP_MISS else "slip_armed", True)
        elif f is Fault.GRIP_MISS:
            self._faults.grip_miss_armed = True
        elif f is Fault.PART_SLIP:
            self._faults.slip_armed = True  # fires once a gripped part is in the air
            self._maybe_slip({p for p in self._gripped if self._in_air(p)})
        elif f is Fault.PROTECTIVE_STOP:
            self.raise_protective_stop(StopReason.INJECTED)
        elif f is Fault.ESTOP:
            self.press_estop()
        else:
            raise ValueError(f"fault {f.value!r} is handled by the backend, not the physics")

    # -- stepping -----------------------------------------------------------------------
    def step_period(self) -> None:
        """Advance the physics by one controller period."""
        data = self.data
        assert self._ids is not None, "build() first"
        if self._stop is not None:
            qd = self._stop.speed(self.time_s)
            self.q_ref = self.q_ref + qd * self.period_s
            self.qd_ref = qd
            if not qd.any():
                self._stop = None
                if self.safety is Safety.EMERGENCY_STOP:
                    self.powered = False  # category 1: power off once standing, brakes on
        # servoJ semantics: be at q_ref at the end of this period. The PD with velocity
        # feed-forward settles onto its position input one physics step ahead, so that
        # input is the set-point one step back along the commanded speed (plus the kv/kp
        # feed-forward term). With several steps per period (CB3) the set-point is
        # interpolated linearly across them.
        self._drive_gripper()
        if self.changer is not None:
            self.changer.drive()
        if self.vacuum is not None:
            self.vacuum.drive()
        k = self.substeps
        if k == 1:
            if self.qd_ref is _ZERO6:
                self._servo_ctrl[:] = self.q_ref
            else:  # ctrl = q_ref + ff_lead * qd_ref, with no temporaries
                np.add(
                    np.multiply(self._ff_lead, self.qd_ref, self._ctrl_tmp),
                    self.q_ref,
                    self._servo_ctrl,
                )
            self._mj.mj_step(self.model, data)
        else:
            # cubic Hermite between the last and this set-point (positions and speeds),
            # so the servo input and its speed feed-forward are continuous (a stepped
            # feed-forward at 125 Hz shakes a gripped part loose)
            ends = np.stack([self._q_prev_ref, self._qd_prev_ref, self.q_ref, self.qd_ref])
            q_sub = self._hermite[0] @ ends
            qd_sub = self._hermite[1] @ ends
            ctrl = q_sub + self._ff_lead * qd_sub
            for s in range(k):
                self._servo_ctrl[:] = ctrl[s]
                self._mj.mj_step(self.model, data)
        self._q_prev_ref = self.q_ref
        self._qd_prev_ref = self.qd_ref
        self._periods += 1
        if self._stop is None:
            self.qd_ref = _ZERO6  # feed-forward is valid for one period only
        self._pressed = False
        self._gripped = self._check_contacts()
        if self._gripped or self._held_at:
            self._note_held(self._gripped, self._pressed)
        if self.vacuum is not None:
            self.vacuum.update()
            self._gripped = self._gripped | self.vacuum.held
        f = self._faults
        if f.slip_armed or f.slipping:
            self._update_faults(self._gripped)
        self._update_inputs()

    def _drive_gripper(self) -> None:
        g = self.description.gripper
        if g is None:
            return
        closing = self.jaws_enabled and self.outputs.get(g.close_output) == g.close_value
        if closing == self._closing and self._jaws_driven:
            return  # the drive forces already in ctrl stay
        if closing and not self._closing and self._faults.grip_miss_armed:
            self._faults.grip_miss_armed = False
            self._move_part_away()
        self._closing = closing
        self._jaws_driven = True
        speed = g.grip_force_N if closing else -g.grip_force_N
        ctrl = self.data.ctrl
        for a in self._jaw_act:
            ctrl[a] = speed  # a force (N): the drives are force actuators

    # -- contacts -----------------------------------------------------------------------
    def contacts_changed(self) -> None:
        """Geoms were switched on or off (a tool change): take their collision kinds anew."""
        m = self.model
        self._kind = [
            int(m.geom_contype[g]) if (m.geom_contype[g] or m.geom_conaffinity[g]) else 0
            for g in range(m.ngeom)
        ]
        self._static_geoms = [g for g, k in enumerate(self._kind) if k == STATIC]
        self._robot_or_pad_geoms = frozenset(
            g for g, k in enumerate(self._kind) if k & (ROBOT | PADS | TOOL)
        )
        self._clean_pairs, self._clean_gripped = None, _NONE

    def contacts_changed_held(self) -> None:
        """The cups sealed on or let go of a part: the verdict on the same contact pairs
        changes (a part held by suction pressed onto a fixture is judged like a gripped one)."""
        held = self.vacuum.held if self.vacuum is not None else _NONE
        self._vac_geoms = frozenset(self.ids.part_geom[n] for n in held)
        self._clean_pairs, self._clean_gripped = None, _NONE

    def _check_contacts(self) -> frozenset[str]:
        """Raise a protective stop on unexpected contact; return the gripped parts.

        Unexpected: the arm, tool or pads against a fixture or the floor; the arm or tool
        (not the pads) against a part that is not gripped. Contacts are few, so a plain
        loop over Python ints beats numpy here (this runs every period). Most periods
        see the same geom pairs as the last one (a part resting, a part held), and the
        verdict on pairs with nothing suspicious among them depends on the pairs alone.
        """
        data = self.data
        if not data.ncon:
            return _NONE
        pairs = data.contact.geom.tolist()
        if pairs == self._clean_pairs:
            return self._clean_gripped
        watched = self._robot_or_pad_geoms | self._vac_geoms
        for g1, g2 in pairs:
            if g1 in watched or g2 in watched:
                break
        else:
            self._clean_pairs, self._clean_gripped = pairs, _NONE
            return _NONE
        kind = self._kind
        pad_hits: dict[int, int] = {}
        robot_parts: list[tuple[int, int]] = []
        suspicious: list[int] = []
        part_static: list[int] = []
        pad_parts: list[tuple[int, int]] = []
        for i, (g1, g2) in enumerate(pairs):
            k1, k2 = kind[g1], kind[g2]
            both = k1 | k2
            if not both & (ROBOT | PADS | TOOL):
                if both == PARTS | STATIC:
                    part_static.append(i)
                continue
            if both & STATIC:
                suspicious.append(i)
            elif both == PADS | PARTS:
                pad, part = (g1, g2) if k1 == PADS else (g2, g1)
                pad_hits[part] = pad_hits.get(part, 0) | (1 if pad == self._pad_a else 2)
                pad_parts.append((i, part))
            elif both == ROBOT | PARTS:
                robot_parts.append((i, g2 if k2 == PARTS else g1))
        gripped_geoms = {g for g, hits in pad_hits.items() if hits == 3}
        carried = gripped_geoms | self._vac_geoms
        suspicious += [i for i, g in robot_parts if g not in carried]
        # a finger landing on a part it does not hold (judged by force, like the tool);
        # a held part that loses one pad's contact for a moment is still held, and the
        # cups pressing on the part they hold are how suction carries it
        held = self._held_at
        suspicious += [
            i for i, g in pad_parts if g not in carried and self._part_of_geom[g] not in held
        ]
        # a carried part pushed into a fixture is a contact like the tool's own; the
        # light touch of setting it down is not (judged each period, so never cached)
        pressed = [i for i in part_static if pairs[i][0] in carried or pairs[i][1] in carried]
        if pressed and self.safety is Safety.NORMAL:
            self._judge_pressed(pressed, gripped_geoms)
        if suspicious and self.safety is Safety.NORMAL:
            self._judge_contacts(suspicious)
        gripped = (
            frozenset(self._part_of_geom[g] for g in gripped_geoms) if gripped_geoms else _NONE
        )
        self._clean_pairs, self._clean_gripped = (
            (None, _NONE) if suspicious or pressed else (pairs, gripped)
        )
        self._pressed = bool(pressed)
        return gripped

    def _judge_contacts(self, indices: list[int]) -> None:
        force = self._force6
        total, worst, worst_i = 0.0, -1.0, indices[0]
        for i in indices:
            self._mj.mj_contactForce(self.model, self.data, i, force)
            total += abs(force[0])
            if abs(force[0]) > worst:
                worst, worst_i = abs(force[0]), i
        if total > self.description.contact_force_limit_N:
            g1, g2 = (self.model.geom(int(g)).name for g in self.data.contact.geom[worst_i])
            self.last_contact = ContactEvent(self.time_s, total, (g1, g2))
            self.raise_protective_stop(StopReason.CONTACT)

    def _judge_pressed(self, indices: list[int], gripped_geoms: set[int]) -> None:
        """A gripped part against a fixture: a protective stop when it is forced back in
        the jaws by more than ``JAM_SLIDE_M`` since it was last free of fixtures (pushed
        into the fixture, not set down on it), or pressed harder than ``JAM_FORCE_N`` beyond
        the parts' own weight (a 12 kg case resting on its conveyor while the cups seal is
        not the arm pressing: UR's force limit sees what the arm adds)."""
        force = self._force6
        total = 0.0
        parts: set[str | None] = set()  # None: a geom of no part
        for i in indices:
            self._mj.mj_contactForce(self.model, self.data, i, force)
            total += abs(force[0])
            parts.update(self._part_of_geom.get(int(g)) for g in self.data.contact.geom[i])
        total -= GRAVITY_M_S2 * sum(self._part_mass_kg.get(p, 0.0) for p in parts if p is not None)
        slide = max(
            (self._slide_in_jaws_m(self._part_of_geom[g]) for g in gripped_geoms), default=0.0
        )
        if slide > JAM_SLIDE_M or total > JAM_FORCE_N:
            g1, g2 = (self.model.geom(int(g)).name for g in self.data.contact.geom[indices[0]])
            self.last_contact = ContactEvent(self.time_s, total, (g1, g2))
            self.raise_protective_stop(StopReason.CONTACT)

    def _part_in_tcp(self, part: str) -> np.ndarray:
        """T_tcp_part: the part's pose in the TCP frame."""
        T_world_tcp = self.tcp_pose_world()
        R_t = T_world_tcp[:3, :3].T
        T_world_part = self.part_pose_world(part)
        T = np.eye(4)
        T[:3, :3] = R_t @ T_world_part[:3, :3]
        T[:3, 3] = R_t @ (T_world_part[:3, 3] - T_world_tcp[:3, 3])
        return T

    def _slide_in_jaws_m(self, part: str) -> float:
        """How far the part was forced back in the jaws (towards the flange, or sideways)
        since it was last free of fixtures; sliding out of them (a slip) does not count."""
        held = self._held_at.get(part)
        if held is None:
            return 0.0
        d = self._part_in_tcp(part)[:3, 3] - held[:3, 3]
        return max(-float(d[2]), math.hypot(float(d[0]), float(d[1])))

    def _note_held(self, gripped: frozenset[str], pressed: bool) -> None:
        """Where each gripped part sits in the jaws while no fixture touches it; kept
        through a period of lost pad contact, handed to the place check once the jaws
        are commanded open."""
        if not self._closing:
            if self._held_at:
                self._held_last, self._held_at = self._held_at, {}
            return
        if gripped and not pressed:
            for name in gripped:
                self._held_at[name] = self._part_in_tcp(name)

    # -- faults ---------------------------------------------------------------------------
    def _update_faults(self, gripped: Set[str]) -> None:
        f = self._faults
        if f.slip_armed:
            self._maybe_slip({p for p in gripped if self._in_air(p)})
        for name in list(f.slipping):
            if not self._touches_pads(name):
                self.model.geom_friction[self.ids.part_geom[name]] = self.ids.part_friction[name]
                f.slipping.discard(name)
        if not f.slipping and self.ids.pad_geoms[0] >= 0:
            self.model.geom_friction[list(self.ids.pad_geoms)] = self.ids.pad_friction

    def _maybe_slip(self, candidates: set[str]) -> None:
        if not candidates:
            return
        self._faults.slip_armed = False
        g = self.description.gripper
        assert g is not None
        for name in candidates:
            self._faults.slipping.add(name)
            # friction such that the two pads hold only a fraction of the weight
            weight = self.model.body_mass[self.ids.part_bodies[name]] * GRAVITY_MPS2
            mu = SLIP_HOLD_FRACTION * weight / (2.0 * g.grip_force_N)
            self.model.geom_friction[self.ids.part_geom[name], 0] = mu
            self.model.geom_friction[list(self.ids.pad_geoms), 0] = mu

    def _contacts_of(self, part: str) -> list[int]:
        """Kinds of the geoms the part touches."""
        g = self.ids.part_geom[part]
        kind = self._kind
        return [
            kind[g2 if g1 == g else g1]
            for g1, g2 in self.data.contact.geom[: self.data.ncon].tolist()
            if g in (g1, g2)
        ]

    def _in_air(self, part: str) -> bool:
        """True when the part touches the finger pads only and is clear of the fixtures."""
        kinds = self._contacts_of(part)
        if not kinds or any(k != PADS for k in kinds):
            return False
        return self._clear_of_static(part)

    def _clear_of_static(self, part: str) -> bool:
        """True when the part is ``AIR_CLEARANCE_M`` clear of every fixture and the floor."""
        g = self.ids.part_geom[part]
        fromto = self._fromto6
        for other in self._static_geoms:
            d = self._mj.mj_geomDistance(self.model, self.data, g, other, AIR_CLEARANCE_M, fromto)
            if d < AIR_CLEARANCE_M:
                return False
        return True

    def _touches_pads(self, part: str) -> bool:
        return PADS in self._contacts_of(part)

    def _move_part_away(self, reach_m: float | None = None) -> None:
        """grip_miss: the part at the gripper (within ``reach_m`` of the TCP; default: the
        jaws' half stroke + 5 cm) is moved 0.15 m towards the robot base."""
        ids, data, g = self.ids, self.data, self.description.gripper
        tcp = data.site_xpos[ids.tcp_site]
        if reach_m is None:
            assert g is not None  # grip_miss without a reach is a jaw gripper's
            reach_m = g.stroke_m / 2 + 0.05
        reach = reach_m
        best, best_d = None, reach
        for name, body in ids.part_bodies.items():
            dist = float(np.linalg.norm(data.xpos[body] - tcp))
            if dist < best_d:
                best, best_d = name, dist
        if best is None:
            return
        adr = ids.part_qpos[best]
        base_xy = self.description.T_world_base[:2, 3]
        direction = base_xy - data.qpos[adr : adr + 2]
        norm = float(np.linalg.norm(direction))
        direction = direction / norm if norm > 1e-6 else np.array([-1.0, 0.0])
        data.qpos[adr : adr + 2] += 0.15 * direction
        data.qvel[self.model.jnt_dofadr[self.model.joint(f"part:{best}").id] + np.arange(6)] = 0.0
        self._mj.mj_forward(self.model, data)

    # -- safety helpers -----------------------------------------------------------------
    def _begin_stop(self, decel_rad_s2: float) -> None:
        qd0 = self.qd_ref.copy() if self._stop is None else self._stop.speed(self.time_s)
        duration = float(np.max(np.abs(qd0))) / decel_rad_s2
        self._stop = _Stop(self.time_s, qd0, duration)

    def _resume(self) -> None:
        self.safety = Safety.NORMAL
        self.stop_time_s = None
        self._stop = None
        self.q_ref = self._q_prev_ref = self.data.qpos[self.ids.qpos].copy()
        self.qd_ref = self._qd_prev_ref = _ZERO6

    # -- measurements ---------------------------------------------------------------------
    def _sensor_channels(self) -> set[str]:
        g = self.description.gripper
        chans = {s.channel for s in self.description.presence_sensors}
        if self.description.vacuum is not None and self.description.vacuum.vacuum_ok_input:
            chans.add(self.description.vacuum.vacuum_ok_input)
        if self.description.tool_changer is not None and self.description.tool_changer.locked_input:
            chans.add(self.description.tool_changer.locked_input)
        if self._rules is not None:
            chans |= self._rules.channels()
        if g is not None:
            chans |= {c for c in (g.closed_sensor_input, g.open_sensor_input) if c}
        return chans

    def jaw_gap_m(self) -> float:
        """Distance between the finger pads (m); stroke when open, 0 when fully closed."""
        g = self.description.gripper
        if g is None:
            return 0.0
        a, b = self._jaw_adr
        return float(g.stroke_m - (self._qpos.item(a) + self._qpos.item(b)))

    def _update_inputs(self) -> None:
        g = self.description.gripper
        if g is not None:
            qpos, qvel = self._qpos.item, self._qvel.item  # Python floats, not numpy scalars
            a, b = self._jaw_adr
            gap = g.stroke_m - (qpos(a) + qpos(b))
            va, vb = self._jaw_dof
            resting = max(abs(qvel(va)), abs(qvel(vb))) < JAW_REST_SPEED_MPS
            lo = g.sensor_min_gap_m
            hi = g.stroke_m - lo
            if g.closed_sensor_input:
                # switches on once the jaws came to rest on something, then reads their
                # position only: jaws that shake on a held part (a stop, a jerk) stay on
                on = resting or self.inputs[g.closed_sensor_input]
                self.inputs[g.closed_sensor_input] = bool(self._closing and on and lo <= gap <= hi)
            if g.open_sensor_input:
                self.inputs[g.open_sensor_input] = gap >= hi
        if self.vacuum is not None and self.vacuum.vac.vacuum_ok_input:
            self.inputs[self.vacuum.vac.vacuum_ok_input] = self.vacuum.vacuum_ok
        if self.changer is not None and self.changer.desc.locked_input:
            self.inputs[self.changer.desc.locked_input] = self.changer.locked
        for sensor in self.description.presence_sensors:
            c = np.asarray(sensor.center_world_m)
            h = np.asarray(sensor.half_extents_m)
            self.inputs[sensor.channel] = any(
                bool(np.all(np.abs(self.data.xpos[b] - c) <= h))
                for b in self.ids.part_bodies.values()
            )
        if self._rules is not None:
            xpos = self.data.xpos
            self.inputs.update(
                self._rules.evaluate(
                    self.time_s,
                    self.outputs,
                    (xpos[b].tolist() for b in self.ids.part_bodies.values()),
                )
            )

    def _raw_wrench_base(self) -> list[float]:
        """External wrench on the tool (payload compensated), base axes, torque at flange:
        (fx, fy, fz, tx, ty, tz) in N and N m.

        MuJoCo's force/torque sensors give the force and torque the flange exerts on the
        tool subtree (tool, fingers, anything they hold), in the ``ft`` site frame. In
        static balance the external wrench is minus that, minus the tool's own weight
        (the configured payload, which UR's controller also compensates). Plain float
        arithmetic: numpy's per-call cost dwarfs 3x3 products, and this runs every period.
        """
        fx, fy, fz, tx, ty, tz = self._ft_flat.tolist()
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = self._R_site_flat.tolist()
        cx, cy, _cz = self._tool_com.tolist()
        sx, sy, _sz = self._site_pos.tolist()
        mg = self._tool_weight_N
        # world axes: minus the sensed wrench (site -> world), minus the tool's weight
        # (0, 0, -mg) and its moment about the flange, (c - s) x (0, 0, -mg)
        ex = -(r00 * fx + r01 * fy + r02 * fz)
        ey = -(r10 * fx + r11 * fy + r12 * fz)
        ez = mg - (r20 * fx + r21 * fy + r22 * fz)
        mx = mg * (cy - sy) - (r00 * tx + r01 * ty + r02 * tz)
        my = -mg * (cx - sx) - (r10 * tx + r11 * ty + r12 * tz)
        mz = -(r20 * tx + r21 * ty + r22 * tz)
        b00, b01, b02, b10, b11, b12, b20, b21, b22 = self._R_base_world_flat
        return [
            b00 * ex + b01 * ey + b02 * ez,
            b10 * ex + b11 * ey + b12 * ez,
            b20 * ex + b21 * ey + b22 * ez,
            b00 * mx + b01 * my + b02 * mz,
            b10 * mx + b11 * my + b12 * mz,
            b20 * mx + b21 * my + b22 * mz,
        ]

    def measure(self) -> RobotState:
        """This period's measurements, as the controller reports them."""
        w = self._raw_wrench_base()
        o0, o1, o2, o3, o4, o5 = self._ft_offset
        wrench = np.array((w[0] - o0, w[1] - o1, w[2] - o2, w[3] - o3, w[4] - o4, w[5] - o5))
        return RobotState(
            self._periods / self._rate_hz,
            self._q_view.copy(),
            self._qd_view.copy(),
            wrench,
            self.safety,
            self.inputs.copy(),
            self.outputs.copy(),
            self.powered,
            self.powered,
        )

    # -- introspection for tests, reports and the renderer (never for the engine) ---------
    def q_measured(self) -> np.ndarray:
        return np.array(self._q_view)

    def tcp_pose_world(self) -> np.ndarray:
        T = np.eye(4)
        T[:3, :3] = self.data.site_xmat[self.ids.tcp_site].reshape(3, 3)
        T[:3, 3] = self.data.site_xpos[self.ids.tcp_site]
        return T

    def feed_parts(self, moved_m: float = 0.01) -> list[str]:
        """The twin's infeed: every part not held that lies more than ``moved_m`` from its
        spawn pose is put back there at rest (a conveyor bringing the next part).
        Returns the names of the parts fed."""
        from scipy.spatial.transform import Rotation

        mujoco = load_mujoco()
        fed = []
        for part in self.description.parts:
            if part.name in self._gripped:
                continue
            spawn = part.T_world_part
            if np.linalg.norm(self.part_pose_world(part.name)[:3, 3] - spawn[:3, 3]) <= moved_m:
                continue
            adr = self.ids.part_qpos[part.name]
            x, y, z, w = Rotation.from_matrix(spawn[:3, :3]).as_quat()
            self.data.qpos[adr : adr + 7] = [*spawn[:3, 3], w, x, y, z]
            dof = self.model.jnt_dofadr[self.model.joint(f"part:{part.name}").id]
            self.data.qvel[dof : dof + 6] = 0.0
            fed.append(part.name)
        if fed:
            mujoco.mj_forward(self.model, self.data)
        return fed

    def placed_offset(self, T_world_tcp: np.ndarray) -> tuple[str, float, float] | None:
        """How far the part released last lies from where a gripper at ``T_world_tcp``
        holding it as it did (before anything pressed it) puts it: (name, distance m,
        angle deg); None when no part was released. Released a little above its support,
        a part falls onto it: up to ``PLACE_DROP_M`` straight down does not count."""
        found = None
        for name, T_tcp_part in self._held_last.items():
            target = T_world_tcp @ T_tcp_part
            actual = self.part_pose_world(name)
            d = actual[:3, 3] - target[:3, 3]
            fall = max(0.0, -float(d[2]) - PLACE_DROP_M) if d[2] < 0 else float(d[2])
            offset_m = math.hypot(float(d[0]), float(d[1]), fall)
            cos = (float(np.trace(target[:3, :3].T @ actual[:3, :3])) - 1.0) / 2.0
            angle_deg = math.degrees(math.acos(max(-1.0, min(1.0, cos))))
            if found is None or offset_m > found[1]:
                found = (name, offset_m, angle_deg)
        return found

    def part_pose_world(self, name: str) -> np.ndarray:
        body = self.ids.part_bodies[name]
        T = np.eye(4)
        T[:3, :3] = self.data.xmat[body].reshape(3, 3)
        T[:3, 3] = self.data.xpos[body]
        return T


_NONE: frozenset[str] = frozenset()
_ZERO6 = np.zeros(6)
_ZERO6.setflags(write=False)


def _hermite_table(substeps: int, period_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Matrices (substeps x 4) giving position and speed at the end of each physics step
    from (q0, qd0, q1, qd1) of a cubic Hermite segment over one period."""
    tau = np.arange(1, substeps + 1) / substeps
    T = period_s
    pos = np.stack(
        [
            2 * tau**3 - 3 * tau**2 + 1,
            (tau**3 - 2 * tau**2 + tau) * T,
            -2 * tau**3 + 3 * tau**2,
            (tau**3 - tau**2) * T,
        ],
        axis=1,
    )
    vel = np.stack(
        [
            (6 * tau**2 - 6 * tau) / T,
            3 * tau**2 - 4 * tau + 1,
            (-6 * tau**2 + 6 * tau) / T,
            3 * tau**2 - 2 * tau,
        ],
        axis=1,
    )
    return pos, vel


def _zero(channel: str) -> float | bool:
    return 0.0 if channel[:2] in ("AI", "AO") else False
