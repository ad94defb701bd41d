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
from cellrunner.sim.faults import Fault, GripFaults, inject
from cellrunner.sim.infeed import attach_equipment
from cellrunner.sim.infeed import feed_parts as _feed_parts
from cellrunner.sim.input_rules import InputRules
from cellrunner.sim.jaw_welds import JawWelds
from cellrunner.sim.jaws import Jaws
from cellrunner.sim.mjcf import PhysicsOptions, compile_model
from cellrunner.sim.model_ids import ModelIds, lookup_ids
from cellrunner.sim.mujoco_loader import load_mujoco
from cellrunner.sim.places import PlaceInspection, Places
from cellrunner.sim.press_fits import PressFits
from cellrunner.sim.safety import STOP_DECEL_RAD_S2, StopRamp, StopReason
from cellrunner.sim.servo import ZERO6 as _ZERO6
from cellrunner.sim.servo import ServoInput
from cellrunner.sim.world_io import IoImage
from cellrunner.sim.world_stops import StopControl
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
        self.io = IoImage(self)
        self.outputs, self.inputs, self._rules = self.io.outputs, self.io.inputs, self.io.rules
        self.stops = StopControl(self)
        # Hot-path views into MjData (its buffers never move). The arm's joints and
        # servos come first in the model, so they are plain slices.
        assert list(ids.qpos) == list(range(6)) and list(ids.dof) == list(range(6))
        assert list(ids.servo) == list(range(6))
        self._q_view = self.data.qpos[0:6]
        self._qd_view = self.data.qvel[0:6]
        self.servo = ServoInput(
            self._mj, self.model, self.data, ids.ff_gain, self.substeps, self.period_s
        )
        self._q_prev_ref = self.q_ref.copy()
        self._qd_prev_ref: np.ndarray = _ZERO6
        self._gripped: frozenset[str] = NONE
        self.wrist = WristSensor(self.data, ids, d.T_world_base)
        self.places = Places(self)
        self.contacts = ContactMonitor(self)
        self.grip_faults = GripFaults(self)
        self.jaws = Jaws(self) if d.gripper is not None else None
        self.jaw_welds = JawWelds(self) if d.gripper is not None and d.parts else None
        self.press_fits = PressFits(self) if d.press_fits and d.parts else None
        self.data.ctrl[ids.servo] = self.q_ref
        self._mj.mj_forward(self.model, self.data)
        self.vacuum, self.intruders, self.changer, self.belts, self.feeder = attach_equipment(self)
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
        self.stops.begin_stop(decel_rad_s2)

    def set_output(self, channel: str, value: bool | float) -> None:
        self.io.set_output(channel, value)

    def set_input(self, channel: str, value: bool | float) -> None:
        """Drive an input that no twin sensor drives (a test or a scripted peer)."""
        self.io.set_input(channel, value)

    def zero_ft_sensor(self) -> None:
        self.wrist.zero()

    def unlock_protective_stop(self) -> None:
        self.stops.unlock_protective_stop()

    def press_estop(self) -> None:
        """A person presses the emergency stop: category 1 stop, then power off."""
        self.stops.press_estop()

    def release_estop(self) -> None:
        """A person twists the e-stop button out; the robot stays off until recovered."""
        self.estop_pressed = False

    def recover_from_estop(self) -> None:
        self.stops.recover_from_estop()

    def raise_protective_stop(self, reason: StopReason = StopReason.INJECTED) -> None:
        self.stops.raise_protective_stop(reason)

    def inject_fault(self, fault: str | Fault) -> None:
        """Make ``fault`` happen physically (see :class:`Fault`); robot_disconnect is the
        backend's business."""
        inject(self, fault)

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
        # servoJ semantics: be at q_ref at the end of this period (see ServoInput)
        self.drive_outputs()
        self.servo.step(data, (self._q_prev_ref, self._qd_prev_ref, self.q_ref, self.qd_ref))
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
        if self.jaw_welds is not None and self.jaw_welds.busy(self._gripped):
            closing = self.jaws is not None and self.jaws.closing
            self.jaw_welds.update(self._gripped, closing, self.grip_faults.slipping)
        if self.vacuum is not None:
            self.vacuum.update()
            self._gripped = self._gripped | self.vacuum.held
        if self.press_fits is not None:
            self.press_fits.update(self._gripped)
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
        return self.servo.inputs(self._q_prev_ref, self._qd_prev_ref, q_rad, qd_rad_s)

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

    # -- measurements ---------------------------------------------------------------------
    def jaw_gap_m(self) -> float:
        """Distance between the finger pads (m); stroke when open, 0 when fully closed."""
        return 0.0 if self.jaws is None else self.jaws.gap_m()

    def _update_inputs(self) -> None:
        self.io.update_inputs()

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
        return _feed_parts(self, moved_m)

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
