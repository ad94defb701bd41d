"""The physics twin of one cell: MuJoCo model and data, stepped one controller period at
a time, with the controller's behaviour around it (servo set-point, safety state, stop
ramps), the IO image and physical fault injection.

The world owns the model, the set-point, the safety state and the IO image, and steps;
its parts each live in their own module and are reached as attributes: ``wrist``
(:mod:`.wrist`), ``contacts`` (:mod:`.contacts`, the contact rules), ``places``
(:mod:`.places`, the place check), ``jaws`` (:mod:`.jaws`), ``grip_faults``
(:mod:`.faults`), ``vacuum`` (:mod:`.vacuum`), ``changer`` (:mod:`.tool_changer`);
stop ramps are :mod:`.safety`'s, indices :mod:`.model_ids`'.

``SimWorld`` knows nothing about trajectories or the engine;
:mod:`cellrunner.backends.sim.backend` wraps it in the
:class:`~cellrunner.backends.base.RobotBackend` Protocol. Everything the engine can
learn comes out of :meth:`SimWorld.measure` (a RobotState: joints, wrist wrench, IO, safety):
fault injections change the physics, never a flag the engine could read.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cellrunner.errors import BackendError
from cellrunner.model.robot_state import RobotState, Safety
from cellrunner.sim.contacts import NONE, ContactEvent, ContactMonitor
from cellrunner.sim.description import TwinDescription
from cellrunner.sim.faults import Fault, GripFaults
from cellrunner.sim.input_rules import InputRules
from cellrunner.sim.jaws import Jaws
from cellrunner.sim.mjcf import PhysicsOptions, compile_model
from cellrunner.sim.model_ids import ModelIds, lookup_ids
from cellrunner.sim.mujoco_loader import load_mujoco
from cellrunner.sim.places import PlaceInspection, Places
from cellrunner.sim.safety import (
    COLLISION_BACKOFF_S,
    STOP_DECEL_RAD_S2,
    UNLOCK_DELAY_S,
    StopRamp,
    StopReason,
)
from cellrunner.sim.servo import hermite_table
from cellrunner.sim.wrist import WristSensor


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
        self._ids: ModelIds | None = None

    # -- lifecycle ----------------------------------------------------------------------
    def build(self) -> None:
        """Compile the model and put the arm at home and the parts at their frames."""
        self._mj = load_mujoco()
        self.model = compile_model(self.description, self.options)
        self.data = self._mj.MjData(self.model)
        self._ids = ids = lookup_ids(self.model, self.description)
        self._periods = 0
        self.data.qpos[ids.qpos] = self.description.q_home_rad
        self._mj.mj_forward(self.model, self.data)
        self.q_ref = np.array(self.description.q_home_rad, dtype=float)
        self.qd_ref = np.zeros(6)
        self.safety = Safety.NORMAL
        self.powered = True
        self.estop_pressed = False
        self.stop_time_s: float | None = None
        self.last_contact: ContactEvent | None = None
        self._stop: StopRamp | None = None
        d = self.description
        self.outputs: dict[str, float | bool] = {c: _zero(c) for c in d.io_outputs}
        self.inputs: dict[str, float | bool] = {c: _zero(c) for c in d.io_inputs}
        self._scripted_inputs: dict[str, float | bool] = {}
        self._rules = InputRules(d.input_rules) if d.input_rules else None
        # Hot-path views into MjData (its buffers never move). The arm's joints and
        # servos come first in the model, so they are plain slices.
        assert list(ids.qpos) == list(range(6)) and list(ids.dof) == list(range(6))
        assert list(ids.servo) == list(range(6))
        self._q_view = self.data.qpos[0:6]
        self._qd_view = self.data.qvel[0:6]
        self._servo_ctrl = self.data.ctrl[0:6]
        self._ctrl_tmp = np.zeros(6)
        # The arm settles one physics step ahead of its servo input (measured), hence -h.
        self._ff_lead = ids.ff_gain - self.period_s / self.substeps
        self._q_prev_ref = self.q_ref.copy()
        self._qd_prev_ref: np.ndarray = _ZERO6
        self._hermite = hermite_table(self.substeps, self.period_s)
        self._gripped: frozenset[str] = NONE
        self.wrist = WristSensor(self.data, ids, d.T_world_base)
        self.places = Places(self)
        self.contacts = ContactMonitor(self)
        self.grip_faults = GripFaults(self)
        self.jaws = Jaws(self) if d.gripper is not None else None
        self.data.ctrl[ids.servo] = self.q_ref
        self._mj.mj_forward(self.model, self.data)
        self.vacuum = None
        if d.vacuum is not None:
            from cellrunner.sim.vacuum import VacuumCups

            self.vacuum = VacuumCups(self, d.vacuum)
        self.intruders = None
        if d.intruders:
            from cellrunner.sim.depth import Intruders

            self.intruders = Intruders(self.model, self.data, d.intruders)
        self.changer = None
        if d.tool_changer is not None:
            from cellrunner.sim.tool_changer import ToolChanger

            self.changer = ToolChanger(self, d.tool_changer)
        self.belts = None
        if d.belts:
            from cellrunner.sim.belts import Belts

            self.belts = Belts(self.model, self.data, d.belts)
        self.feeder = None
        if d.feed is not None:
            from cellrunner.sim.feed import Feeder

            self.feeder = Feeder(self, d.feed)
        self._update_inputs()

    @property
    def built(self) -> bool:
        return self.data is not None

    @property
    def time_s(self) -> float:
        """Simulated time (s), counted in whole controller periods (no float drift)."""
        return self._periods / self._rate_hz

    @property
    def ids(self) -> ModelIds:
        """The built model's indices (joints, parts, pads, sites)."""
        if self._ids is None:
            raise RuntimeError("the twin's model is not built yet; call build() first")
        return self._ids

    @property
    def mujoco(self) -> Any:
        """The ``mujoco`` module this world was built with."""
        return self._mj

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
        q = np.array(q_rad, dtype=float)
        self.data.qpos[self.ids.qpos] = q
        self.data.qvel[self.ids.dof] = 0.0
        self.q_ref = self._q_prev_ref = q.copy()
        self.qd_ref = self._qd_prev_ref = _ZERO6
        self._mj.mj_forward(self.model, self.data)

    @property
    def holding(self) -> bool:
        """Whether the next period holds the set-point where it is: none was sent since
        the last period (no speed feed-forward) and no stop ramp moves it."""
        return self.qd_ref is _ZERO6 and self._stop is None

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
        self.wrist.zero()

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
            self.grip_faults.grip_miss_armed = True
        elif f is Fault.PART_SLIP:
            self.grip_faults.arm_slip(self._gripped)  # fires once a gripped part is in the air
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
        if self.intruders is not None and self.intruders.update(self.time_s):
            self._mj.mj_kinematics(self.model, data)
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
        self.drive_outputs()
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
        self._after_physics()

    def _after_physics(self) -> None:
        """What the controller and the line make of a period's physics: contacts (a
        protective stop), the held parts, the cups, faults, the inputs."""
        contacts = self.contacts
        if self.belts is not None:
            self.belts.update()
        if self.intruders is not None:
            self.intruders.note_contacts()
        self._gripped = contacts.check()
        if self._gripped or contacts.held_at:
            contacts.note_held(self._gripped, self.jaws is not None and self.jaws.closing)
        if self.vacuum is not None:
            self.vacuum.update()
            self._gripped = self._gripped | self.vacuum.held
        if self.grip_faults.active:
            self.grip_faults.update(self._gripped)
        self._update_inputs()

    # -- look-ahead (many periods of a planned motion in one call) -------------------------
    def drive_outputs(self) -> None:
        """Follow the outputs (jaws, tool changer, cups), as each period starts."""
        if self.jaws is not None:
            self.jaws.drive()
        if self.changer is not None:
            self.changer.drive()
        if self.vacuum is not None:
            self.vacuum.drive()

    def servo_inputs(self, q_rad: np.ndarray, qd_rad_s: np.ndarray) -> np.ndarray:
        """The arm servos' inputs for consecutive periods whose set-points are the rows of
        ``q_rad``/``qd_rad_s`` (the first row being the set-point now commanded): one row
        per physics step, computed exactly as :meth:`step_period` does."""
        k = self.substeps
        if k == 1:
            return np.asarray(np.add(np.multiply(self._ff_lead, qd_rad_s), q_rad))
        rows = np.empty((len(q_rad) * k, 6))
        q_prev, qd_prev = self._q_prev_ref, self._qd_prev_ref
        for i in range(len(q_rad)):
            ends = np.stack([q_prev, qd_prev, q_rad[i], qd_rad_s[i]])
            rows[i * k : (i + 1) * k] = self._hermite[0] @ ends + self._ff_lead * (
                self._hermite[1] @ ends
            )
            q_prev, qd_prev = q_rad[i], qd_rad_s[i]
        return rows

    def advanced(self, periods: int, q_ref_rad: np.ndarray, qd_ref_rad_s: np.ndarray) -> None:
        """The physics was advanced ``periods`` whole periods in one go (the data now holds
        the last one's step), the last of them with set-point ``q_ref_rad``/``qd_ref_rad_s``:
        bring the world's own state to where :meth:`step_period` would have left it."""
        self.q_ref = self._q_prev_ref = q_ref_rad
        self._qd_prev_ref = qd_ref_rad_s
        self.qd_ref = _ZERO6
        self._periods += periods
        self._after_physics()

    @property
    def periods(self) -> int:
        """Controller periods simulated since build."""
        return self._periods

    @property
    def gripped(self) -> frozenset[str]:
        """The parts the jaws (or cups) held at the last period."""
        return self._gripped

    @property
    def input_rules(self) -> InputRules | None:
        return self._rules

    # -- contacts -----------------------------------------------------------------------
    def contacts_changed(self) -> None:
        """Geoms were switched on or off (a tool change): take their collision kinds anew."""
        self.contacts.geoms_changed()

    def contacts_changed_held(self) -> None:
        """The cups sealed on or let go of a part."""
        self.contacts.suction_changed(self.vacuum.held if self.vacuum is not None else NONE)

    # -- safety helpers -----------------------------------------------------------------
    def _begin_stop(self, decel_rad_s2: float) -> None:
        qd0 = self.qd_ref.copy() if self._stop is None else self._stop.speed(self.time_s)
        self._stop = StopRamp.from_speed(self.time_s, qd0, decel_rad_s2)

    def _resume(self) -> None:
        self.safety = Safety.NORMAL
        self.stop_time_s = None
        self._stop = None
        self.q_ref = self._q_prev_ref = self.data.qpos[self.ids.qpos].copy()
        self.qd_ref = self._qd_prev_ref = _ZERO6

    # -- measurements ---------------------------------------------------------------------
    def _sensor_channels(self) -> set[str]:
        chans = {s.channel for s in self.description.presence_sensors}
        if self.description.vacuum is not None and self.description.vacuum.vacuum_ok_input:
            chans.add(self.description.vacuum.vacuum_ok_input)
        if self.description.tool_changer is not None and self.description.tool_changer.locked_input:
            chans.add(self.description.tool_changer.locked_input)
        if self._rules is not None:
            chans |= self._rules.channels()
        if self.jaws is not None:
            chans |= self.jaws.channels()
        return chans

    def jaw_gap_m(self) -> float:
        """Distance between the finger pads (m); stroke when open, 0 when fully closed."""
        return 0.0 if self.jaws is None else self.jaws.gap_m()

    def _update_inputs(self) -> None:
        if self.jaws is not None:
            self.jaws.update_inputs(self.inputs)
        if self.vacuum is not None and self.vacuum.vac.vacuum_ok_input:
            self.inputs[self.vacuum.vac.vacuum_ok_input] = self.vacuum.vacuum_ok
        if self.changer is not None and self.changer.desc.locked_input:
            self.inputs[self.changer.desc.locked_input] = self.changer.locked
        for sensor in self.description.presence_sensors:
            self.inputs[sensor.channel] = any(
                bool(sensor.sees(self.data.xpos[b])) for b in self.ids.part_bodies.values()
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

    def measure(self) -> RobotState:
        """This period's measurements, as the controller reports them."""
        return RobotState(
            self._periods / self._rate_hz,
            self._q_view.copy(),
            self._qd_view.copy(),
            self.wrist.wrench(),
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
        """The twin's infeed before a job. With a feed (``sim: feed``), a new part at its
        frame unless one lies there (:mod:`.feed`). Without one, every part not held that
        lies more than ``moved_m`` from its spawn pose is put back there at rest.
        Returns the names of the parts fed."""
        from scipy.spatial.transform import Rotation

        if self.feeder is not None:
            new = self.feeder.feed()
            return [new] if new is not None else []
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

    def inspect_place(self, T_world_tcp: np.ndarray) -> PlaceInspection | None:
        """See :meth:`.places.Places.inspect`."""
        return self.places.inspect(T_world_tcp)

    def part_velocity_world(self, name: str) -> np.ndarray:
        """The part's linear velocity (m/s, world)."""
        dof = self.model.jnt_dofadr[self.model.joint(f"part:{name}").id]
        return np.array(self.data.qvel[dof : dof + 3])

    def part_pose_world(self, name: str) -> np.ndarray:
        body = self.ids.part_bodies[name]
        T = np.eye(4)
        T[:3, :3] = self.data.xmat[body].reshape(3, 3)
        T[:3, 3] = self.data.xpos[body]
        return T


_ZERO6 = np.zeros(6)
_ZERO6.setflags(write=False)


def _zero(channel: str) -> float | bool:
    return 0.0 if channel[:2] in ("AI", "AO") else False
