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
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.errors import BackendError, PeerUnreachable
from cellrunner.model.robot_state import RobotState, Safety
from cellrunner.model.trajectory import ApprovedTrajectory
from cellrunner.sim.description import TwinDescription, dh_forward
from cellrunner.sim.faults import Fault
from cellrunner.sim.mjcf import PhysicsOptions
from cellrunner.sim.world import SimWorld

if TYPE_CHECKING:
    from cellrunner.backends.sim.depth import TwinDepthRenderer
    from cellrunner.sim.lookahead import Lookahead, Preview
    from cellrunner.sim.places import PlaceInspection

# servoJ set-points further apart than the joint speed limit allows (with this margin)
# are refused, as the controller would protective-stop on them.
SET_POINT_JUMP_MARGIN = 1.5
#: a look-ahead covers this many periods at first, doubling while they pass whole up
#: to the most; one cut short (a contact, an input, a check ahead) starts again small,
#: since its physics beyond the cut is computed in vain
AHEAD_FIRST_PERIODS = 64
AHEAD_MAX_PERIODS = 1024
#: a hold's look-ahead starts this small when an output changed since the last
#: look-ahead (the jaws moving soon cut it: a contact, the sensor), else at most this
#: big (a hold's end in time bounds it too)
AHEAD_FIRST_HOLD_PERIODS = 16
AHEAD_CALM_HOLD_PERIODS = 256


class SimBackend:
    """The MuJoCo twin as a robot. Construct (no work), ``connect()`` (builds the model),
    then ``servo``/``wait_period`` cycles, ``close()``."""

    def __init__(self, description: TwinDescription, options: PhysicsOptions | None = None) -> None:
        self.description = description
        self._imagers: dict[str, Any] = {}  # camera name -> CameraImager, made on first use
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
        self._ahead: Lookahead | None = None
        self._ahead_cap = AHEAD_FIRST_PERIODS  # grows while look-aheads pass whole
        self._ahead_not_before = 0  # no look-ahead before this period (a cut one's end)
        # a hold's cap, apart: it starts small again when an output changed (the jaws
        # moving soon end a hold's quiet stretch, and the periods rolled out beyond such a
        # cut are wasted)
        self._hold_cap = AHEAD_FIRST_HOLD_PERIODS
        self._ahead_outputs: dict[str, bool | float] | None = None  # at the last look-ahead
        self._max_step_rad = (
            np.radians(description.spec.joint_speed_max_deg_s)
            / self.rate_hz
            * SET_POINT_JUMP_MARGIN
        )

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
            self._lookahead(world)  # its scratch data is built with the model
        self._connected = True
        self._link_lost = False

    def close(self) -> None:
        for imager in self._imagers.values():
            imager.close()
        self._imagers.clear()
        self._fresh = None
        if self.world is not None and self._connected:
            self.world.stop_motion()
        self._connected = False
        self.world = None
        self._accepted = None
        self._ahead = None

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
            jump = np.abs(q - world.q_ref)
            if (jump > self._max_step_rad).any():
                j = int(np.argmax(jump - self._max_step_rad))
                raise BackendError(
                    f"set-point {index} of step {trajectory.step_index} ({trajectory.step_name}) "
                    f"jumps {np.degrees(jump[j]):.2f} deg on joint {j + 1} in one period; the "
                    f"joint speed limit allows {np.degrees(self._max_step_rad[j]):.2f} deg"
                )
        world.command(q, qd_all[index])
        self._next_index, self._last_q = index + 1, q

    # -- look-ahead: many periods of a streamed motion per call (sim.lookahead) --------------
    def look_ahead(
        self, trajectory: ApprovedTrajectory, next_index: int, periods: int
    ) -> Preview | None:
        """The coming periods' measurements if ``trajectory`` keeps streaming (set-point
        ``next_index - 1``, the one commanded last, then one more each period), without
        taking them yet; None when the twin cannot look ahead now. Covers at most
        ``periods`` periods (fewer after a look-ahead that was cut short)."""
        world = self.world
        accepted = self._accepted
        if (
            world is None
            or not self._connected
            or accepted is None
            or accepted[0] is not trajectory
            or next_index != self._next_index
            or world.q_ref is not self._last_q
            or next_index < 1
            or world.periods < self._ahead_not_before
        ):
            return None
        self._outputs_changed(world)
        self._hold_cap = AHEAD_CALM_HOLD_PERIODS
        n = min(periods, self._ahead_cap, len(accepted[1]) - next_index + 1)
        j0 = next_index - 1
        preview = self._lookahead(world).preview(accepted[1][j0 : j0 + n], accepted[2][j0 : j0 + n])
        if self._cut_short(world, preview, n):
            self._ahead_cap = AHEAD_FIRST_PERIODS
        return preview

    def look_ahead_hold(self, periods: int) -> Preview | None:
        """The coming periods' measurements if the set-point stays where it is (a step
        waiting with the arm still), without taking them yet; None when the twin cannot
        look ahead now. Covers at most ``periods`` periods."""
        world = self.world
        if (
            world is None
            or not self._connected
            or world.periods < self._ahead_not_before
            or world.stopping
        ):
            return None
        if self._outputs_changed(world):
            self._hold_cap = AHEAD_FIRST_HOLD_PERIODS
        n = min(periods, self._hold_cap)
        preview = self._lookahead(world).preview_hold(n)
        if self._cut_short(world, preview, n):
            self._hold_cap = AHEAD_FIRST_HOLD_PERIODS
        return preview

    def _lookahead(self, world: SimWorld) -> Lookahead:
        """The world's look-ahead engine, made at the first look-ahead."""
        if self._ahead is None:
            from cellrunner.sim.lookahead import Lookahead

            self._ahead = Lookahead(world)
        return self._ahead

    def _outputs_changed(self, world: SimWorld) -> bool:
        """Whether the outputs changed since the last look-ahead (remembered from now)."""
        if world.outputs == self._ahead_outputs:
            return False
        self._ahead_outputs = dict(world.outputs)
        return True

    def _cut_short(self, world: SimWorld, preview: Preview | None, n: int) -> bool:
        """Whether ``preview`` of ``n`` periods ends before them: the period after its
        quiet ones is no plain motion or hold, so no look-ahead starts before it."""
        if preview is None or preview.quiet >= n:
            return False
        self._ahead_not_before = world.periods + preview.quiet + 1
        return True

    def commit_look_ahead(self, preview: Preview, periods: int) -> None:
        """Take over the first ``periods`` periods of ``preview`` (at most its quiet
        ones): the twin then stands where that many ``wait_period`` calls, with
        ``servo`` sending the trajectory's set-points between them (none for a hold),
        would have left it."""
        assert self._ahead is not None and self.world is not None  # a preview was made
        self._fresh = None
        self._ahead.commit(preview, periods)
        if preview.holds:
            if periods == preview.periods:
                self._hold_cap = min(2 * self._hold_cap, AHEAD_MAX_PERIODS)
            return
        self._last_q = self.world.q_ref
        self._next_index += periods
        if periods == preview.periods:
            self._ahead_cap = min(2 * self._ahead_cap, AHEAD_MAX_PERIODS)

    def discard_look_ahead(self, preview: Preview) -> None:
        """A preview none of whose periods is taken (the next period runs as usual)."""
        if preview.holds:
            self._hold_cap = AHEAD_FIRST_HOLD_PERIODS
        else:
            self._ahead_cap = AHEAD_FIRST_PERIODS

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
        belts = self._world().belts
        if belts is None or name not in belts.descs:
            return None
        return belts.travel_m(name)

    def set_belt_speed(self, name: str, speed_mps: float) -> None:
        """Run the twin's belt ``name`` at ``speed_mps`` (0 stops it): what a line does
        to the cell, for tests and benches."""
        belts = self._world().belts
        if belts is None:
            raise BackendError(f"the twin has no belt {name!r}")
        self._fresh = None
        belts.set_speed(name, speed_mps)

    def jump_belt_encoder(self, name: str, distance_m: float) -> None:
        """An encoder fault on the twin's belt ``name``: its reading jumps by
        ``distance_m`` while the belt runs on (for tests and benches)."""
        belts = self._world().belts
        if belts is None:
            raise BackendError(f"the twin has no belt {name!r}")
        self._fresh = None
        belts.jump_encoder(name, distance_m)

    def job_started(self) -> None:
        """A job starts now: the twin's scheduled intruders (``sim: intruders``) count from
        here."""
        world = self._world()
        if world.intruders is not None:
            world.intruders.start(world.time_s)

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
        from cellrunner.backends.sim.depth import TwinDepthRenderer
        from cellrunner.sim.depth import DepthImager

        description = next((c for c in self.description.cameras if c.name == camera), None)
        if description is None:
            raise BackendError(f"the twin has no camera {camera!r}")
        imager = DepthImager(
            self._world().model, description, range_m, self.description.depth_noise_m, seed=seed
        )
        return TwinDepthRenderer(imager)

    def inject_intrusion(self, T_world_box: np.ndarray) -> str | None:
        """``--inject intrusion@STEP``: drop the twin's box at ``T_world_box`` now (it
        stays); its name, or None when the cell has none (not watched)."""
        self._fresh = None
        world = self._world()
        if world.intruders is None:
            return None
        return world.intruders.inject(T_world_box, world.time_s)

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
        from cellrunner.sim.cameras import CameraImager

        world = self._world()
        imagers = self._imagers
        if name not in imagers:
            camera = next((c for c in self.description.cameras if c.name == name), None)
            if camera is None:
                raise BackendError(f"the twin has no camera {name!r}")
            imagers[name] = CameraImager(world.model, camera)
        return np.asarray(imagers[name].image(np.array(world.data.qpos)))

    def tcp_tracking_error_m(self) -> float:
        """Distance (m) between the TCP at the last set-point and the measured TCP."""
        world = self._world()
        q = world.q_measured()
        T_ft = self.description.T_flange_tcp
        p_ref = (dh_forward(self.description.spec, world.q_ref) @ T_ft)[:3, 3]
        p_act = (dh_forward(self.description.spec, q) @ T_ft)[:3, 3]
        return float(np.linalg.norm(p_ref - p_act))

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
        """Check an approved trajectory once (seal, rate, speed) and remember it with its
        joint positions and speeds.

        The seal is verified on the first set-point of each trajectory object and
        remembered by identity: ApprovedTrajectory is frozen and its arrays read-only.
        """
        if not isinstance(trajectory, ApprovedTrajectory) or not trajectory.is_sealed:
            raise BackendError(
                "refusing an unsealed trajectory: only trajectories approved by check can move "
                "the robot"
            )
        traj = trajectory.trajectory
        if abs(traj.rate_hz - self.rate_hz) > 1e-9:
            raise BackendError(
                f"trajectory sampled at {traj.rate_hz:g} Hz, the controller runs "
                f"at {self.rate_hz:g} Hz"
            )
        steps = np.abs(np.diff(traj.q_rad, axis=0))
        if len(steps) and (steps > self._max_step_rad).any():
            i, j = np.unravel_index(int(np.argmax(steps - self._max_step_rad)), steps.shape)
            raise BackendError(
                f"set-point {i + 1} of step {trajectory.step_index} ({trajectory.step_name}) "
                f"jumps {np.degrees(steps[i, j]):.2f} deg on joint {j + 1} in one period; the "
                f"joint speed limit allows {np.degrees(self._max_step_rad[j]):.2f} deg"
            )
        self._accepted = (trajectory, traj.q_rad, traj.qd_rad_s)
        self._next_index, self._last_q = -1, None
        return self._accepted
