"""The jog and servo session: commands from one input (keys, a gamepad, a SpaceMouse, a
program over UDP) through :class:`cellrunner.commissioning.servo.Servo`, speedJ out at the
controller rate through ur_rtde, and a screen showing the input, the TCP pose, the
governor's scale and why it slows.

On a terminal the screen is redrawn in place; without one (the input is not the keyboard)
each change of status is one line on ``out``. A device that goes away stops the arm and
ends the session (:class:`InputLost`, exit 3); SIGTERM or Ctrl-C stops the arm and ends it.

A watched cell (SPEC section 12) is jogged with its zone watch: the depth feed starts once
the arm is connected, each period stamps its images with the measured joints, and the
governor slows and stops the arm short of what the map holds, naming the voxel.
"""

from __future__ import annotations

import math
import re
import sys
import threading
import time
from typing import TYPE_CHECKING, Any, TextIO

import numpy as np

from cellrunner.commissioning.inputs import InputLost
from cellrunner.commissioning.jog import Governor
from cellrunner.commissioning.servo import Servo, Tick
from cellrunner.errors import ConnectionLost, PeerUnreachable
from cellrunner.model.geometry import rpy_deg_of
from cellrunner.thread_priority import Previous, realtime, restore

if TYPE_CHECKING:
    from cellrunner.commissioning.inputs import InputSource
    from cellrunner.execution.watch import SourceDepthFeed, ZoneWatch
    from cellrunner.planning.world import CellWorld

#: screen refresh (s)
SCREEN_S = 0.1
#: a session ends by itself after this long (s)
MAX_SESSION_S = 4 * 3600.0
#: speedJ's acceleration (rad/s^2): above what the smoothing filter asks, so speedJ
#: follows it; also the brake of a stop
SPEEDJ_ACCEL_RAD_S2 = 8.0


#: SCHED_FIFO priority of the servo loop (below the twin's controller loop, 20)
SERVO_PRIORITY = 10


class JogSession:
    """Construct, :meth:`connect`, :meth:`run` (until the input quits or ``stop`` is
    set), :meth:`close`."""

    def __init__(
        self,
        world: CellWorld,
        host: str,
        source: InputSource,
        out: TextIO | None = None,
        screen: bool | None = None,
        watched: tuple[ZoneWatch, SourceDepthFeed] | None = None,
    ) -> None:
        self.world, self.host, self.source = world, host, source
        self.kinematics = world.kinematics
        self.zone: ZoneWatch | None = watched[0] if watched is not None else None
        self.feed: SourceDepthFeed | None = watched[1] if watched is not None else None
        self.servo = Servo(world, Governor(world.kinematics, world.collision, self.zone))
        self.out = out if out is not None else sys.stdout
        self.screen = self.out.isatty() if screen is None else screen
        # ur_rtde's RTDEControlInterface and RTDEReceiveInterface (untyped bindings)
        self._control: Any = None
        self._receive: Any = None
        self.status = "stopped"
        self.realtime = False
        self._priority_before: Previous | None = None
        self._said = ""
        #: the link to the controller dropped and ur_rtde's interfaces were left as they
        #: were: end the process with os._exit, not through their destructors
        self.abandoned = False

    def connect(self) -> None:
        self.source.open()  # a missing terminal, device or port fails before the arm is touched
        # the loop (and ur_rtde's threads, started below, which inherit it) at real-time
        # priority where the OS allows it, as a servo node runs: a loaded machine then
        # delays the arm's commands by microseconds, not by the scheduler's slices
        self._priority_before = realtime(SERVO_PRIORITY)
        self.realtime = self._priority_before is not None
        from cellrunner.backends.ur_probe import controller_version

        controller_version(self.host, 3.0)
        import rtde_control
        import rtde_receive

        try:
            rate = self.world.spec.rate_hz
            self._receive = rtde_receive.RTDEReceiveInterface(
                self.host, rate, ["timestamp", "actual_q", "actual_qd", "safety_mode"]
            )
            self._control = rtde_control.RTDEControlInterface(self.host, rate)
        except (RuntimeError, OSError) as exc:
            raise PeerUnreachable(f"cannot jog the arm at {self.host}: {exc}") from exc
        if self.feed is not None:
            self.feed.measured(self._receive.getTimestamp(), np.array(self._receive.getActualQ()))
            self.feed.start()

    def close(self) -> None:
        try:
            if self.feed is not None:
                self.feed.close()
            if self._link_lost():
                # a controller that is gone has stopped its arm. Asking it again blocks in
                # ur_rtde's reconnect loop for minutes, and disconnecting (or destroying)
                # the interfaces waits 0.5 s each on their reconnecting threads: they are
                # kept, untouched, for the process to end without them (:attr:`abandoned`)
                self.abandoned = True
                return
            if self._control is not None:
                try:
                    self._control.speedStop(SPEEDJ_ACCEL_RAD_S2)
                    self._control.stopScript()
                finally:
                    self._control.disconnect()
            if self._receive is not None:
                self._receive.disconnect()
        finally:
            self.source.close()
            restore(self._priority_before)  # the caller's thread, as it was before connect
            self._priority_before = None

    def _link_lost(self) -> bool:
        return any(
            interface is not None and not interface.isConnected()
            for interface in (self._control, self._receive)
        )

    def run(self, stop: threading.Event | None = None) -> None:
        stop = stop or threading.Event()
        period_s = self.servo.period_s
        next_screen = 0.0
        t_end = time.monotonic() + MAX_SESSION_S
        try:
            while time.monotonic() < t_end and not stop.is_set():
                t_start = self._control.initPeriod()
                now = time.monotonic()
                try:
                    command = self.source.poll(now)
                except InputLost:
                    self._control.speedStop(SPEEDJ_ACCEL_RAD_S2)  # at once, not at close()
                    self.status = "stopped: the input went away"
                    raise
                if self.source.quit_requested:
                    return
                if not self._receive.isConnected():
                    raise ConnectionLost(f"lost the connection to the arm at {self.host}")
                q = np.array(self._receive.getActualQ())
                if self.feed is not None:
                    self.feed.measured(self._receive.getTimestamp(), q)
                tick = self.servo.step(q, command, now)
                self._control.speedJ(
                    [float(x) for x in tick.qd_rad_s], SPEEDJ_ACCEL_RAD_S2, period_s
                )
                self.status = self._status(tick, now)
                if now >= next_screen:
                    self._show(q, tick, now)
                    next_screen = now + SCREEN_S
                self._control.waitPeriod(t_start)
        except KeyboardInterrupt:
            return
        except RuntimeError as exc:
            # ur_rtde's calls raise RuntimeError when its reconnect to a controller that
            # is gone gives up ("Timeout connecting to UR dashboard server")
            if not (self._link_lost() or "connect" in str(exc) or "receive" in str(exc)):
                raise
            raise ConnectionLost(f"lost the connection to the arm at {self.host}: {exc}") from exc
        finally:
            if not self.screen:
                self._say(f"input {self.source.name}: {self.source.status(time.monotonic())}")

    def _say(self, line: str) -> None:
        self.out.write(line + "\n")
        self.out.flush()
        self._said = line

    def _status(self, tick: Tick, now: float) -> str:
        v = tick.verdict
        if not tick.commanded:
            moving = np.any(tick.qd_rad_s)
            return "braking" if moving else f"stopped ({self.source.idle_reason(now)})"
        if v is None:
            return "stopped (inside the dead band)"
        if v.scale >= 1:
            return f"moving {self._describe(tick)}"
        if v.scale > 0:
            return f"slowing ({v.scale * 100:.0f}%): {v.reason}"
        return f"stopped: {v.reason}"

    @staticmethod
    def _describe(tick: Tick) -> str:
        v = tick.velocity
        if tick.frame == "joint":
            return "joints [" + ", ".join(f"{math.degrees(x):.1f}" for x in v) + "] deg/s"
        lin = ", ".join(f"{x * 1000:.0f}" for x in v[:3])
        ang = ", ".join(f"{math.degrees(x):.1f}" for x in v[3:])
        return f"{tick.frame} [{lin}] mm/s [{ang}] deg/s"

    def _zone_line(self, q: np.ndarray) -> list[str]:
        if self.zone is None:
            return []
        m, where = self.zone.clearance_m(q)
        if not where:
            return ["watched zone: clear"]
        return [f"watched zone: {where}, {m * 1000:.0f} mm beyond the padding"]

    def _show(self, q: np.ndarray, tick: Tick, now: float) -> None:
        if not self.screen:  # one line per change (counters and figures aside)
            line = f"input {self.source.name}: {self.status}"
            if re.sub(r"[-+\d.]+", "", line) != re.sub(r"[-+\d.]+", "", self._said):
                self._say(line)
            return
        T = self.kinematics.T_world_tcp(q)
        verdict = tick.verdict or self.servo.governor.judge(q, np.zeros(6))
        scale = f"{verdict.scale * 100:.0f}%" if tick.verdict else "-"
        xyz = ", ".join(f"{v:.4f}" for v in T[:3, 3])
        rpy = ", ".join(f"{v:.2f}" for v in rpy_deg_of(T[:3, :3]))
        lines = [
            f"cellrunner jog  {self.source.header()}",
            self.source.status(now),
            f"TCP (world): xyz [{xyz}] m  rpy [{rpy}] deg",
            f"joints: [{', '.join(f'{math.degrees(v):.2f}' for v in q)}] deg",
            f"nearest obstacle: {verdict.nearest} {verdict.clearance_m * 1000:.0f} mm beyond its clearance",
            *self._zone_line(q),
            f"singularity distance: {verdict.singularity}",
            f"governor scale: {scale}",
            f"status: {self.status}",
        ]
        self.out.write("\x1b[H\x1b[2J" + "\r\n".join(lines) + "\r\n")
        self.out.flush()
