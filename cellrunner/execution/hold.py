"""A held job (PackML Holding, Held). A requested hold (the PLC's JobHold, its watchdog)
waits for Unhold or Abort. A protective stop is unlocked once the controller allows it
and the job resumed, as the task's ``on_protective_stop`` says: automatically up to
``max`` stops, else only on the PLC's Unhold (serve) or not at all (the job ends)."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np

from cellrunner.backends.base import ExplainsStops
from cellrunner.errors import BackendError
from cellrunner.execution.context import JobContext
from cellrunner.model.hold_source import HoldSource
from cellrunner.model.robot_state import Safety
from cellrunner.model.task import ProtectiveStopPolicy

#: the controller refuses to unlock a protective stop sooner (UR e-Series and CB3)
UNLOCK_DELAY_S = 5.0
#: how long recovery may keep trying to unlock before the job ends with code 100
RECOVERY_TIMEOUT_S = 30.0
#: a refused unlock is tried again this often, not every period (s)
UNLOCK_RETRY_S = 0.25
#: protective stops of one step with the TCP this close (m) came at the same place
SAME_PLACE_M = 0.02

PROTECTIVE_STOP = HoldSource.PROTECTIVE_STOP.reason  # the reason of a hold the robot's stop started


class Held(enum.Enum):
    WAIT = "wait"  # still held
    RESUME = "resume"  # the arm may move again: resume the step
    FAILED = "failed"  # the job ends with 100 (:attr:`JobHold.failure` says why)


@dataclass
class JobHold:
    """The hold under way (``reason``) and the protective stops of the job so far."""

    policy: ProtectiveStopPolicy
    wait_for_unhold: bool = False  # serve: a stop past the policy waits for the PLC's Unhold
    reason: str = ""
    source: HoldSource | None = None  # who held (None: not held yet)
    since_s: float = 0.0
    unhold_requested: bool = False  # the PLC's Unhold during a protective stop's hold
    failure: str = ""
    stops_at: list[tuple[int, np.ndarray]] = field(default_factory=list)  # (step, q rad)
    _unlock_at_s: float = 0.0  # robot time of the next unlock attempt

    @property
    def protective(self) -> bool:
        return self.reason == PROTECTIVE_STOP

    def enter(self, source: HoldSource, now_s: float, step: int | None, q_rad: np.ndarray) -> None:
        """JobHold asked by ``source`` at ``now_s`` (s), in step ``step`` (None: between
        steps) with the arm at ``q_rad``."""
        self.source, self.reason = source, source.reason
        self.since_s, self.unhold_requested = now_s, False
        if self.protective and step is not None:
            self.stops_at.append((step, q_rad.copy()))

    def poll(self, ctx: JobContext, stops: int, step: int | None, label: str) -> Held:
        """A protective stop's hold, once per tick: unlock it when the controller allows
        it (one attempt per UNLOCK_RETRY_S), resume when the arm may move. ``stops``:
        protective stops of the job so far; ``step``, ``label``: the step under way."""
        held_for = ctx.now_s - self.since_s
        automatic = self.policy.resume and stops <= self.policy.max
        if not automatic and not self.unhold_requested:
            if self.wait_for_unhold:
                return Held.WAIT
            why = (
                "the task does not resume after protective stops"
                if not self.policy.resume
                else f"more than {self.policy.max} protective stops" + self._same_place(ctx, step)
            )
            return self._failed(f"protective stop during {label}: {_cause(ctx)}{why}")
        if held_for < UNLOCK_DELAY_S:
            return Held.WAIT
        if ctx.last_state.safety is Safety.PROTECTIVE_STOP:
            if ctx.now_s < self._unlock_at_s:
                return Held.WAIT  # bounded work: one attempt per UNLOCK_RETRY_S
            self._unlock_at_s = ctx.now_s + UNLOCK_RETRY_S
            try:
                ctx.backend.unlock_protective_stop()
            except BackendError as exc:
                if held_for > UNLOCK_DELAY_S + RECOVERY_TIMEOUT_S:
                    return self._failed(f"protective stop not recovered: {exc}")
                return Held.WAIT
        return Held.RESUME if ctx.read().safety is Safety.NORMAL else Held.WAIT

    def _failed(self, message: str) -> Held:
        self.failure = message
        return Held.FAILED

    def _same_place(self, ctx: JobContext, step: int | None) -> str:
        """What the protective stops of ``step`` say when they all came at the same place
        (the TCP within ``SAME_PLACE_M``), else nothing."""
        here = [q for i, q in self.stops_at if i == step]
        if len(here) < 2:
            return ""
        tcp = np.array([ctx.motions.tcp_position_m(q) for q in here])
        spread_m = float(np.linalg.norm(tcp[:, None] - tcp[None], axis=2).max())
        if spread_m > SAME_PLACE_M:
            return ""
        which = "both" if len(here) == 2 else f"all {len(here)}"
        return (
            f", {which} with the TCP within {spread_m * 1000:.0f} mm: something there stops "
            "the arm each time"
        )


def _cause(ctx: JobContext) -> str:
    """What raised the protective stop under way, as the backend knows it ("pad 'jaw_a'
    met fixture 'infeed_table' at 673 N: "), else nothing."""
    backend = ctx.backend
    cause = backend.stop_cause() if isinstance(backend, ExplainsStops) else None
    return f"{cause}: " if cause else ""
