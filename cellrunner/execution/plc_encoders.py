"""The belts whose encoder the PLC counts (``encoder: {source: plc, register: 20,
ticks_per_m}``, SPEC section 13), measured for ``serve``: the engine's belt watch
(:mod:`.belt_watch`) reads a PLC belt's travel here, from the PLC server's holding
registers, and every other belt's from the backend as before.

The PLC writes the count (uint32, high word first, wrapping) into two of its registers
20-29 every scan, changed or not. The engine reads it every period (2 ms on a UR), the
PLC writes every scan (10-20 ms): a belt read as the count alone would look like a
staircase, standing still between writes and jumping 3-6 mm at each (at 0.3 m/s), while
the tracked stretch follows the line of the belt's measured speed within a mm.

**Extrapolated, not interpolated.** Each write the engine sees is a sample: its time is
the period the engine saw it in (the engine's clock, the one the arm's set-points and
the eye's edges are timed by), its travel the unwrapped count / ticks_per_m. The travel
the engine reads is the least-squares line through the samples of the last
``FIT_WINDOW_S``, extrapolated to the period: between writes it runs on at the belt's
speed, and at each write it moves by a fraction of the new sample's offset from the
line. Interpolating between the last two samples would be as smooth but lags a whole
scan behind the newest count; and taking each count as it comes (running on from it at
the speed) makes the travel step by the jitter of each write's arrival (a write late by
2 ms is 0.6 mm at 0.3 m/s), and a PLC's thread kept from the interpreter delays writes
by tens of ms. The tracked stretch follows the speed the engine measured (the travel
over 0.1 s) for seconds and stops once the belt is 5 mm off that line: in the serve test
on the twin, running on from each count as it came stopped the arm 2.1 s into the
stretch; a line fitted over 0.25 s measured 0.298 m/s for 0.300 and stopped it 2.3-2.6 s
in. The line over ``FIT_WINDOW_S`` averages the jitter out: its speed is the belt's
within 2 mm/s (writes every 12 ms, up to 3 ms late: within 1.7 mm/s, the travel within
0.33 mm of a fixed offset). A belt that changes its speed (or an encoder that jumps)
leaves the line: ``RESTART_SAMPLES`` samples in a row more than ``RESTART_M`` off it on
the same side start the line again from them, so a belt that stops is seen as one within
three or four scans (the PLC keeps writing the same count; a belt stopping dead from 0.3
m/s reads up to 15 mm past its stop meanwhile, back on it 60 ms after); one late write alone (the
Modbus server's thread kept from the interpreter a few ms) does not. A write late or
lost is bridged at the speed until the count is stale.

**A stale count.** A PLC belt is not measured (its travel is None, as for a backend that
cannot read it) until the PLC's first write of its registers, and while the PLC is
silent: no write for longer than ``STALE_S`` (the PLC, or the link, stopped). The engine
then holds the belt's last travel and forgets its speed: a ``track`` step waits for a
measured speed (and ends at the step's timeout); a tracked stretch that is running sees
the belt leave the line of its speed and ends in a controlled stop (100): the arm does
not follow a belt it cannot see. The next write measures the belt again.

A count that has not changed for longer than ``STALE_S`` while it was moving (at the
speed it had when it last changed it should have moved on by more than ``STALE_TICKS``
ticks) while the PLC keeps writing it is logged (``plc_encoder_stale``: a frozen count,
or a belt stopped hard); the data cannot tell the two apart, so the belt is taken as it
reads, stopped, and what the engine does for a belt that stops applies: a tracked
stretch that is running ends in a controlled stop (100) once the belt is 5 mm off its
measured speed, which at 0.3 m/s is within two scans of the count's last change.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from itertools import pairwise
from typing import TYPE_CHECKING

from cellrunner.execution.context import QUIET, EventLog
from cellrunner.model.encoder_count import WrappingCount

if TYPE_CHECKING:
    from cellrunner.backends.base import MeasuresConveyors
    from cellrunner.model.conveyor import Conveyor

#: what the PLC server publishes: (how many writes of the encoder registers came so far,
#: the PLC's holding registers from 0, at least up to 29, as the last one left them)
Registers = tuple[int, Sequence[int]]

#: the line is fitted to the samples of this long, s
FIT_WINDOW_S = 0.5
#: a shorter span of samples gives no speed yet (the travel holds between writes)
MIN_SPEED_SPAN_S = 0.02
#: this many samples in a row this far off the line, on the same side, start it again (m)
RESTART_SAMPLES = 3
RESTART_M = 0.006
#: no write (or no change of a moving count) for longer than this is a stale count, s:
#: a few scans, and the Modbus server's thread kept from the interpreter by planning
#: (writes then arrive late, in bursts: up to 55 ms apart measured, under load)
STALE_S = 0.2
#: a count is moving when it should have changed by more than this many ticks meanwhile
STALE_TICKS = 3.0


@dataclass
class PlcBelt:
    """One belt's count as the PLC writes it, sampled by the engine; see the module
    docstring."""

    register: int
    ticks_per_m: float
    count: WrappingCount = field(default_factory=WrappingCount)
    writes: int = 0  # the PLC server's write counter when this belt was sampled last
    #: (engine time, travel m) of each write seen, newest last
    samples: deque[tuple[float, float]] = field(default_factory=lambda: deque(maxlen=512))
    written_s: float | None = None  # engine time of the last write seen
    changed_s: float | None = None  # ... of the last change of the count
    speed_at_change_mps: float = 0.0
    #: the line through the samples: (mean time s, slope m/s, mean travel m)
    fit: tuple[float, float, float] = (0.0, 0.0, 0.0)
    stale: str = ""  # why the belt is not measured: the PLC is silent ("" while it writes)
    frozen: str = ""  # why the count looks stale while the PLC writes it ("" while not)

    def travel_m(self, registers: Registers, time_s: float) -> float | None:
        """The belt's travel at engine time ``time_s`` (m, from the first count seen),
        with the PLC server's ``registers``; None before the first write and while the
        count is stale."""
        writes, words = registers
        if writes != self.writes:
            self.writes = writes
            self._sample(time_s, (words[self.register] << 16) | words[self.register + 1])
        if self.written_s is None:
            return None
        self.stale, self.frozen = self._silent(time_s), self._frozen(time_s)
        if self.stale:
            return None
        return self._line(time_s)

    def speed_mps(self) -> float:
        """The slope of the line through the samples, m/s (0 until they span
        ``MIN_SPEED_SPAN_S``)."""
        return self.fit[1]

    def _line(self, time_s: float) -> float:
        t_mean, speed, s_mean = self.fit
        return s_mean + speed * (time_s - t_mean)

    def _sample(self, time_s: float, raw: int) -> None:
        before = self.count.raw
        travel = self.count.note(raw) / self.ticks_per_m
        samples = self.samples
        if samples and time_s <= samples[-1][0]:
            samples.pop()  # two writes in one period: the newer one
        samples.append((time_s, travel))
        while len(samples) > 2 and time_s - samples[0][0] > FIT_WINDOW_S:
            samples.popleft()
        # the belt left the line (it sped up, slowed down, stopped or jumped): the last
        # RESTART_SAMPLES samples off it on the same side; the line starts again from them
        n = RESTART_SAMPLES
        off = [s - self._line(t) for t, s in list(samples)[-n:]] if len(samples) > n else []
        if len(off) == n and _growing(off):
            for _ in range(len(samples) - n):
                samples.popleft()
        self.fit = _fit(samples)
        self.written_s = time_s
        if raw != before:
            self.changed_s = time_s
            self.speed_at_change_mps = self.speed_mps()

    def _silent(self, time_s: float) -> str:
        assert self.written_s is not None
        silent = time_s - self.written_s
        if silent > STALE_S:
            return f"no write of registers {self.register}-{self.register + 1} for {silent:.3f} s"
        return ""

    def _frozen(self, time_s: float) -> str:
        if self.changed_s is None:
            return ""
        still = time_s - self.changed_s
        due = abs(self.speed_at_change_mps) * self.ticks_per_m * still
        if still > STALE_S and due > STALE_TICKS:
            return (
                f"the count in registers {self.register}-{self.register + 1} has not changed "
                f"for {still:.3f} s after the belt ran at {self.speed_at_change_mps:.3f} m/s"
            )
        return ""


def _growing(off: list[float]) -> bool:
    """Whether offsets from the line, oldest first, all lie more than ``RESTART_M`` off it
    on one side and grow away from it: a belt that changed its speed, not the jitter of
    the writes' arrival (which scatters them)."""
    sign = 1.0 if off[-1] > 0 else -1.0
    away = [sign * d for d in off]
    return away[0] > RESTART_M and all(b > a for a, b in pairwise(away))


def _fit(samples: deque[tuple[float, float]]) -> tuple[float, float, float]:
    """The least-squares line through ``samples``: (mean time, slope, mean travel); a
    level line at the newest travel while they span less than ``MIN_SPEED_SPAN_S``."""
    t_last, s_last = samples[-1]
    if t_last - samples[0][0] < MIN_SPEED_SPAN_S:
        return (t_last, 0.0, s_last)
    n = len(samples)
    t_mean = sum(t for t, _ in samples) / n
    s_mean = sum(s for _, s in samples) / n
    var = sum((t - t_mean) ** 2 for t, _ in samples)
    cov = sum((t - t_mean) * (s - s_mean) for t, s in samples)
    return (t_mean, cov / var, s_mean)


class PlcEncoders:
    """The engine's measurement of a cell's belts in ``serve``: a PLC belt's travel from
    the PLC server's registers (``registers()``, read every period), every other one's
    from ``backend`` (None: a backend that measures none). Logs each stale spell of a
    count once, as it starts, and when the count is back."""

    def __init__(
        self,
        conveyors: Mapping[str, Conveyor],
        registers: Callable[[], Registers],
        backend: MeasuresConveyors | None,
        log: EventLog = QUIET,
    ) -> None:
        self.registers = registers
        self.backend = backend
        self.log = log
        self.belts: dict[str, PlcBelt] = {}
        for name, c in conveyors.items():
            enc = c.encoder
            if enc.source == "plc" and enc.register_ is not None and enc.ticks_per_m:
                self.belts[name] = PlcBelt(enc.register_, float(enc.ticks_per_m))

    def conveyor_travel_at_m(self, name: str, time_s: float) -> float | None:
        """How far conveyor ``name`` has travelled at engine time ``time_s``, m; None when
        it is not measured (see :meth:`PlcBelt.travel_m`, or the backend's own)."""
        belt = self.belts.get(name)
        if belt is None:
            return None if self.backend is None else self.backend.conveyor_travel_m(name)
        was = bool(belt.stale or belt.frozen)
        travel = belt.travel_m(self.registers(), time_s)
        why = belt.stale or belt.frozen
        if why and not was:
            self.log.warning("plc_encoder_stale", conveyor=name, why=why, measured=not belt.stale)
        elif was and not why:
            self.log.info("plc_encoder_back", conveyor=name)
        return travel


def has_plc_encoders(conveyors: Mapping[str, Conveyor]) -> bool:
    """Whether any of ``conveyors`` has its encoder counted by the PLC."""
    return any(c.encoder.source == "plc" for c in conveyors.values())
