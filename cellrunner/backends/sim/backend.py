"""The ``sim`` robot backend: the :class:`RobotBackend` Protocol over the MuJoCo twin.

It behaves like the UR controller seen through ur_rtde, on simulated time: ``servo``
is servoJ (one set-point per period, only from sealed approved trajectories),
``wait_period`` advances the physics by one controller period (1/rate_hz) instead of
sleeping, the 5 s protective-stop unlock rule counts simulated seconds, and an e-stop
needs a (simulated) person to release it before ``recover_from_estop``.

Fault injection (``inject_fault``) is for the dry-run command only. It changes the
physics or the connection, never a flag in :class:`RobotState`: the engine has to
notice a missed or slipped part through the jaw sensor and the wrist load.
"""

from __future__ import annotations

from collections.abc import Generator
from typing import TYPE_CHECKING

import numpy as np

from cellrunner.backends.sim import line
from cellrunner.backends.sim.cameras import TwinCameras
from cellrunner.backends.sim.pacing import LookaheadPacer
from cellrunner.backends.sim.setpoints import (
    SET_POINT_JUMP_MARGIN as SET_POINT_JUMP_MARGIN,
)
from cellrunner.backends.sim.setpoints import (
    accept,
    check_jump,
    step_limit_rad,
    tracking_error_m,
)
from cellrunner.errors import BackendError, PeerUnreachable
from cellrunner.model.robot_state import RobotState, Safety
from cellrunner.model.trajectory import ApprovedTrajectory
from cellrunner.sim.description import TwinDescription
from cellrunner.sim.faults import Fault
from cellrunner.sim.mjcf import PhysicsOptions
from cellrunner.sim.world import SimWorld

if TYPE_CHECKING:
    from cellrunner.backends.sim.depth import TwinDepthRenderer
    from cellrunner.sim.lookahead import Preview
    from cellrunner.sim.places import PlaceInspection


class SimBackend:
    """The MuJoCo twin as a robot. Construct (no work), ``connect()`` (builds the model),
    then ``servo``/``wait_period`` cycles, ``close()``."""

    def __init__(self, description: TwinDescription, options: PhysicsOptions | None = None) -> None:
        self.description = description
        self._cameras = TwinCameras(description)
        self.options = options if options is not None else PhysicsOptions()
        self.rate_hz = description.rate_hz
        #: the twin's link comes back only through ``connect()`` (see :meth:`reconnect`)
        self.reconnect_timeout_s = 0.0
        self.world: SimWorld | None = None
        self._connected = False
        self._link_lost = False
        self._last_state: RobotState | None = None
        self._fresh: RobotState | None = None  # this period's measurement, until anything changes
        # the trajectory servo last accepted, with its positions and speeds
        self._accepted: tuple[ApprovedTrajectory, np.ndarray, np.ndarray] | None = None
        self._next_index = -1
        self._last_q: np.ndarray | None = None
        self._pacer = LookaheadPacer(self)
        self._max_step_rad = step_limit_rad(description.spec.joint_speed_max_deg_s, self.rate_hz)

    # -- lifecycle --------------------------------------------------------------------------
    def connect(self) -> None:
        """Build the twin (first call) and connect; after a ``robot_disconnect`` fault this
        reconnects to the same, still running, twin."""
        self._fresh = None
        if self.world is None:
            world = SimWorld(self.description, self.options)
            try:
                world.build()
            except ValueError as exc:
                raise BackendError(str(exc)) from exc
            self.world = world
            self._pacer.lookahead(world)  # its scratch data is built with the model
        self._connected = True
        self._link_lost = False

    def close(self) -> None:
        self._cameras.close()
        self._fresh = None
        if self.world is not None and self._connected:
            self.world.stop_motion()
        self._connected = False
        self.world = None
        self._accepted = None
        self._pacer.ahead = None

    @property
    def sim_time_s(self) -> float:
        """Simulated time since connect (s)."""
        return self._world().time_s

    # -- Protocol -------------------------------------------------------------------------
    def read_state(self) -> RobotState:
        fresh = self._fresh
        if fresh is not None and self._connected:  # measured this period, nothing changed since
            return fresh
        world = self._world()
        if self._link_lost:
            last = self._last_state
            assert last is not None
            return RobotState(
                time_s=world.time_s,
                q_rad=last.q_rad,
                qd_rad_s=last.qd_rad_s,
                wrench_N=last.wrench_N,
                safety=Safety.DISCONNECTED,
                inputs=last.inputs,
                outputs=last.outputs,
                powered=last.powered,
                brakes_released=last.brakes_released,
            )
        self._require_connection()
        if self._fresh is not None:  # measured this period, nothing changed since
            return self._fresh
        state = world.measure()
        self._last_state = self._fresh = state
        return state

    def servo(self, trajectory: ApprovedTrajectory, index: int) -> None:
        world = self.world
        if world is None or not self._connected:
            world = self._world()
            self._require_connection()
        accepted = self._accepted
        if accepted is None or accepted[0] is not trajectory:
            accepted = self._accept(trajectory)
        _, q_all, qd_all = accepted
        if not 0 <= index < len(q_all):
            raise BackendError(f"set-point index {index} out of range 0..{len(q_all) - 1}")
        q = q_all[index]
        # Consecutive set-points of an accepted trajectory were checked against the speed
        # limit once; only a set-point that does not follow the last one is checked here
        # (after the safety state, which world.command checks for the others).
        if index != self._next_index or world.q_ref is not self._last_q:
            world.check_can_move()
            check_jump(trajectory, index, q, world.q_ref, self._max_step_rad)
        world.command(q, qd_all[index])
        self._next_index, self._last_q = index + 1, q

    # -- look-ahead: many periods of a streamed motion per call (sim.lookahead) --------------
    def look_ahead(
        self, trajectory: ApprovedTrajectory, next_index: int, periods: int
    ) -> Preview | None:
        """See :meth:`.pacing.LookaheadPacer.look_ahead`."""
        return self._pacer.look_ahead(trajectory, next_index, periods)

    def look_ahead_hold(self, periods: int) -> Preview | None:
        """See :meth:`.pacing.LookaheadPacer.look_ahead_hold`."""
        return self._pacer.look_ahead_hold(periods)

    def commit_look_ahead(self, preview: Preview, periods: int) -> None:
        """See :meth:`.pacing.LookaheadPacer.commit_look_ahead`."""
        self._pacer.commit_look_ahead(preview, periods)

    def discard_look_ahead(self, preview: Preview) -> None:
        """A preview none of whose periods is taken (the next period runs as usual)."""
        self._pacer.discard_look_ahead(preview)

    def wait_period(self) -> None:
        self._fresh = None
        self._world().step_period()

    def stop_motion(self) -> None:
        self._fresh = None
        self._require_connection()
        self._world().stop_motion()

    def set_output(self, channel: str, value: bool | float) -> None:
        self._fresh = None
        self._require_connection()
        self._world().set_output(channel, value)

    def zero_ft_sensor(self) -> None:
        self._fresh = None
        self._require_connection()
        self._world().zero_ft_sensor()

    def set_tool(
        self, T_flange_tcp: np.ndarray, payload_kg: float, payload_cog_m: tuple[float, float, float]
    ) -> None:
        """Nothing to tell the twin: its tool changer swaps TCP, payload and shapes itself,
        driven by the changer's lock output, as the real changer does."""
        self._require_connection()

    def unlock_protective_stop(self) -> None:
        self._fresh = None
        self._require_connection()
        self._world().unlock_protective_stop()

    def stop_cause(self) -> str | None:
        """The contact that raised the protective stop under way ("pad 'jaw_a' met fixture
        'infeed_table' at 673 N"), or None (no stop, or one a contact did not raise)."""
        world = self.world
        if world is None or world.safety is not Safety.PROTECTIVE_STOP:
            return None
        hit = world.last_contact
        if hit is None or hit.time_s != world.stop_time_s:
            return None
        return hit.describe()

    def recover_from_estop(self) -> None:
        self._fresh = None
        self._require_connection()
        self._world().recover_from_estop()

    def recover_from_estop_steps(self) -> Generator[None, None, None]:
        """The twin re-arms at once: one step."""
        self.recover_from_estop()
        yield

    # -- the simulated world around the robot ---------------------------------------------
    def inject_fault(self, fault: str | Fault) -> None:
        """Make a fault happen now (dry-run ``--inject``): ``grip_miss`` (the part is moved
        away when the jaws next start closing), ``part_slip`` (a gripped part loses its
        grip once in the air), ``protective_stop``, ``estop`` (pressed until
        :meth:`release_estop`), ``robot_disconnect`` (the link drops; ``connect`` again)."""
        self._fresh = None
        f = Fault.parse(fault)
        world = self._world()
        if f is Fault.ROBOT_DISCONNECT:
            if self._connected:
                self.read_state()  # the last state the engine would have received
            world.stop_motion()  # servoJ timeout on the controller: the arm stops
            self._connected = False
            self._link_lost = True
        else:
            world.inject_fault(f)

    def reconnect(self, timeout_s: float | None = None) -> None:
        """The twin's link does not come back after an injected ``robot_disconnect`` (that
        is what the fault rehearses: code 102); call ``connect()`` to restore it."""
        self._fresh = None
        if self._link_lost:
            raise PeerUnreachable("the twin's robot link was cut (robot_disconnect) and stays down")

    def feed_parts(self) -> list[str]:
        """Put parts that were taken away back at their spawn pose (the twin's infeed)."""
        self._fresh = None
        return self._world().feed_parts()

    def conveyor_travel_m(self, name: str) -> float | None:
        """How far belt ``name`` has travelled, m, as its encoder reads it now (None: the
        twin has no such belt)."""
        return line.conveyor_travel_m(self._world(), name)

    def set_belt_speed(self, name: str, speed_mps: float, ramp_mps2: float | None = None) -> None:
        """Run the twin's belt ``name`` at ``speed_mps`` (0 stops it), at once or along a
        drive's ramp of ``ramp_mps2``: what a line does to the cell, for tests and benches."""
        belts = line.belts_of(self._world(), name)
        self._fresh = None
        belts.set_speed(name, speed_mps, ramp_mps2)

    def jump_belt_encoder(self, name: str, distance_m: float) -> None:
        """An encoder fault on the twin's belt ``name``: its reading jumps by
        ``distance_m`` while the belt runs on (for tests and benches)."""
        belts = line.belts_of(self._world(), name)
        self._fresh = None
        belts.jump_encoder(name, distance_m)

    def job_started(self) -> None:
        """A job starts now: the twin's scheduled intruders (``sim: intruders``) count from
        here."""
        line.job_started(self._world())

    def depth_rates_hz(self) -> dict[str, float]:
        """The twin's depth cameras (``sim: depth``) and their frame rates (Hz)."""
        return {name: rate for name, _, _, rate in self.description.depth}

    def depth_time_s(self) -> float | None:
        """Simulated time (s); None when not connected."""
        return None if self.world is None else self.world.time_s

    def depth_scene(self) -> object:
        """The twin's joints and mocap bodies now, copied (:class:`.depth.DepthScene`)."""
        from cellrunner.backends.sim.depth import DepthScene

        return DepthScene.of(self._world().data)

    def depth_renderer(
        self, camera: str, range_m: tuple[float, float], seed: int
    ) -> TwinDepthRenderer:
        """A renderer of the twin's depth camera ``camera`` with the cell's depth noise
        (``sim: depth_noise``); raises BackendError for a camera the twin does not have."""
        return self._cameras.depth_renderer(self._world(), camera, range_m, seed)

    def inject_intrusion(self, T_world_box: np.ndarray) -> str | None:
        """``--inject intrusion@STEP``: drop the twin's box at ``T_world_box`` now (it
        stays); its name, or None when the cell has none (not watched)."""
        self._fresh = None
        return line.inject_intrusion(self._world(), T_world_box)

    def release_estop(self) -> None:
        """A person releases the e-stop button (the robot stays off until recovered)."""
        self._fresh = None
        self._world().release_estop()

    def set_input(self, channel: str, value: bool | float) -> None:
        """Drive an input no twin sensor drives (e.g. a PLC's part_present in a test)."""
        self._fresh = None
        self._world().set_input(channel, value)

    def inspect_place(self, T_world_tcp: np.ndarray) -> PlaceInspection | None:
        """The twin's place inspection: where the part just set down rests against where
        a TCP at ``T_world_tcp`` puts it (:meth:`.places.Places.inspect`)."""
        return self._world().inspect_place(T_world_tcp)

    def camera_image(self, name: str) -> np.ndarray:
        """What cell camera ``name`` sees now (RGB, height x width x 3, uint8), rendered
        from the twin through the camera's intrinsics (:class:`CameraImager`)."""
        return self._cameras.camera_image(self._world(), name)

    def tcp_tracking_error_m(self) -> float:
        """Distance (m) between the TCP at the last set-point and the measured TCP."""
        world = self._world()
        return tracking_error_m(self.description, world.q_ref, world.q_measured())

    # -- helpers ----------------------------------------------------------------------------
    def _world(self) -> SimWorld:
        if self.world is None:
            raise BackendError("sim backend is not connected; call connect() first")
        return self.world

    def _require_connection(self) -> None:
        if not self._connected:
            raise BackendError(
                "robot connection lost"
                if self._link_lost
                else "sim backend is not connected; call connect() first"
            )

    def _accept(
        self, trajectory: ApprovedTrajectory
    ) -> tuple[ApprovedTrajectory, np.ndarray, np.ndarray]:
        """Check an approved trajectory once (seal, rate, speed: :func:`.setpoints.accept`)
        and remember it with its joint positions and speeds.

        The seal is verified on the first set-point of each trajectory object and
        remembered by identity: ApprovedTrajectory is frozen and its arrays read-only.
        """
        self._accepted = accept(trajectory, self.rate_hz, self._max_step_rad)
        self._next_index, self._last_q = -1, None
        return self._accepted
