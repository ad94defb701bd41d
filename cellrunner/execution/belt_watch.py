"""The engine's view of the cell's conveyors (SPEC section 13), updated every period it
reads the robot's state: each belt's travel from its encoder, its measured speed (the
travel over the last ``SPEED_WINDOW_S``), and the parts its photo-eye latched (the travel
at each rising edge of the eye's input, oldest first; the edge is taken in the middle of
the period it came in). A belt whose encoder cannot be read in a period keeps its travel and
loses its speed (measured again from the next readings): ``serve`` reads the PLC's
encoders (:mod:`.plc_encoders`), which say so while the PLC is silent.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol, runtime_checkable

if TYPE_CHECKING:
    from cellrunner.backends.base import MeasuresConveyors
    from cellrunner.model.conveyor import Conveyor
    from cellrunner.model.robot_state import RobotState

#: the belt's speed is its travel over this long, s
SPEED_WINDOW_S = 0.1
#: at most this many latched parts are kept per belt (the oldest drop out)
MAX_LATCHED = 64


@runtime_checkable
class MeasuresConveyorsAt(Protocol):
    """A measurement of the belts that takes the period's time (the PLC's encoders,
    extrapolated to it between the PLC's writes)."""

    def conveyor_travel_at_m(self, name: str, time_s: float) -> float | None:
        """How far conveyor ``name`` has travelled at engine time ``time_s``, m; None when
        it is not measured."""


@dataclass
class BeltView:
    """One conveyor as the engine measures it."""

    name: str
    eye_channel: str
    eye_on: bool = False
    travel_m: float | None = None
    latched_m: deque[float] = field(default_factory=lambda: deque(maxlen=MAX_LATCHED))
    history: deque[tuple[float, float]] = field(default_factory=lambda: deque(maxlen=4096))

    def speed_mps(self) -> float | None:
        """The travel over the last ``SPEED_WINDOW_S`` per s; None until measured that long."""
        if len(self.history) < 2:
            return None
        t1, s1 = self.history[-1]
        for t0, s0 in reversed(self.history):
            if t1 - t0 >= SPEED_WINDOW_S - 1e-9:
                return (s1 - s0) / (t1 - t0)
        return None


class BeltWatch:
    """Every belt of a cell the backend can measure."""

    def __init__(
        self,
        backend: MeasuresConveyors | MeasuresConveyorsAt,
        conveyors: dict[str, Conveyor],
        inputs: dict[str, str],
    ) -> None:
        self.backend = backend
        self.belts = {
            name: BeltView(name, inputs[c.trigger.input]) for name, c in conveyors.items()
        }

    def note(self, state: RobotState) -> None:
        """One period's state: encoder travel, the eye's edges."""
        for belt in self.belts.values():
            travel = (
                self.backend.conveyor_travel_at_m(belt.name, state.time_s)
                if isinstance(self.backend, MeasuresConveyorsAt)
                else self.backend.conveyor_travel_m(belt.name)
            )
            if travel is None:
                belt.history.clear()  # the speed is measured again from the next readings
                continue
            history = belt.history
            if history and state.time_s <= history[-1][0]:
                history.pop()  # the same period read again
            history.append((state.time_s, travel))
            while len(history) > 2 and state.time_s - history[1][0] > 2 * SPEED_WINDOW_S:
                history.popleft()
            on = bool(state.inputs.get(belt.eye_channel))
            if on and not belt.eye_on:
                # the part crossed the eye during the period just past: at its middle
                before = belt.travel_m if belt.travel_m is not None else travel
                belt.latched_m.append((before + travel) / 2)
            belt.travel_m = travel
            belt.eye_on = on
