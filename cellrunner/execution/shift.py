"""A shift in rehearsal (SPEC 13, ``dry-run CELL TASK --shift 8h``): the task back to back
for that much simulated time, faults drawn at their per-job rates, recoveries as on the
line, and the figures a line engineer answers for (parts per hour, availability, MTBF,
MTTR, the result codes, the slowest steps, the first job of each failure to replay).

How the shift is computed (docs/shift.md says it for users):

- **Jobs in order.** Job n places into the pattern's next empty slot (a slot moves on
  only when its job ended OK; after the last slot the pallet is swapped for an empty
  one, as a line does). With ``feed_every_s`` a part arrives every that many seconds and
  a job starts no earlier than its part.
- **Faults.** Before each job, each fault of the rates is drawn once with its
  probability (a seeded generator: the same seed, the same shift), at a step where it
  can happen (a grip miss at a grip, a slip while a part is carried, the others during
  a motion). The engine recovers as it would on the line: retries, a protective stop
  resumed, on_error steps. A job that completes NOK (no part, part lost, place failed:
  the PLC sees DONE) lets the line go on; a job that ends with a fault code (the PLC
  sees ERROR) stops it: the operator clears and resets it (``operator_s``).
- **The twin, once per distinct job.** A job with no fault is the same physics every
  time its slot comes round (the twin is deterministic; the pallet is in the same state
  at the same slot), so the fault-free jobs of one pattern are rehearsed once, in one
  twin, in order, and each slot's job is reused. A job with faults is rehearsed on its
  own, from a fresh twin with the earlier slots filled: exactly what its replay command
  line (``-p`` values and ``--inject``) does, so a failure of the shift is rehearsed again
  alone with the same faults and the same result. The same (slot, faults) is rehearsed
  once.
- **The figures.** ``parts_good``: jobs that ended OK; ``parts_bad``: the others (a part
  that did not reach its slot). A failure is a job that stopped the line (a fault code).
  Downtime: each failure's job time plus the operator's;
  ``availability`` = (shift - downtime) / shift; ``mtbf_s`` = (shift - downtime) /
  failures; ``mttr_s`` = downtime / failures (None without a failure). Jobs a fault
  struck that still ended OK are ``recovered`` (their extra time is a loss of pace,
  not downtime).
"""

from __future__ import annotations

import math
import random
import time
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from cellrunner.errors import InternalError, UsageError
from cellrunner.model.cellport import COMPLETED_CODES
from cellrunner.model.step import Step, StepKind

#: the operator's time to clear and reset a cell whose job failed (s): walk up, read the
#: alarm, take the part out, Clear, Reset
OPERATOR_S = 60.0
#: the slowest steps the report lists
SLOWEST_STEPS = 5
#: faults a shift draws, and where in a job each can happen
MOTION_KINDS = frozenset(
    {
        StepKind.MOVE,
        StepKind.APPROACH,
        StepKind.DESCEND,
        StepKind.LINEAR,
        StepKind.LIFT,
        StepKind.RETREAT,
    }
)
SHIFT_FAULTS = (
    "grip_miss",
    "part_slip",
    "protective_stop",
    "estop",
    "robot_disconnect",
    "plc_disconnect",
)


@dataclass(frozen=True)
class ShiftPlan:
    """What to rehearse: ``duration_s`` of simulated time, ``rates`` (fault -> probability
    per job, 0..1), the generator's ``seed``, a part every ``feed_every_s`` (0: always
    one waiting) and the operator's ``operator_s`` after a failed job."""

    duration_s: float
    rates: Mapping[str, float] = field(default_factory=dict)
    seed: int = 0
    feed_every_s: float = 0.0
    operator_s: float = OPERATOR_S


@dataclass(frozen=True)
class Timeline:
    """One distinct job as the twin rehearsed it: its result, its cycle (s), its retries
    and its steps (kind, name, duration s)."""

    code: int
    result_text: str
    cycle_s: float
    retries: int
    steps: tuple[tuple[str, str, float], ...]

    @property
    def ok(self) -> bool:
        return self.code == 0

    @property
    def stops_the_line(self) -> bool:
        """Ended with a fault code (the PLC sees ERROR): the operator must clear it."""
        return self.code not in COMPLETED_CODES

    @classmethod
    def of(cls, payload: Mapping[str, Any]) -> Timeline:
        """From a rehearsed job's JSON payload."""
        return cls(
            int(payload["result_code"]),
            str(payload["result_text"]),
            float(payload["cycle_time_s"]),
            int(payload.get("retries", 0)),
            tuple(
                (str(s["kind"]), str(s["name"]), float(s["duration_s"]))
                for s in payload["steps"]
                if s.get("status") != "pending"
            ),
        )


#: a drawn fault: (fault name, expanded step index)
Drawn = tuple[tuple[str, int], ...]


def draw_faults(rng: random.Random, rates: Mapping[str, float], steps: Sequence[Step]) -> Drawn:
    """The faults of one job: each fault of ``rates`` (in their sorted order, so the draw
    does not depend on the file's order) with its probability, at a step where it can
    happen; none where the task has no such step."""
    drawn = []
    for fault in sorted(rates):
        if rng.random() >= rates[fault]:
            continue
        where = eligible_steps(fault, steps)
        if where:
            drawn.append((fault, where[rng.randrange(len(where))]))
    return tuple(drawn)


def eligible_steps(fault: str, steps: Sequence[Step]) -> list[int]:
    """The expanded step indices where ``fault`` can strike."""
    if fault == "grip_miss":
        return [s.index for s in steps if s.kind == StepKind.GRIP]
    if fault == "part_slip":  # while a part is carried: between a grip and its release
        carried, out = False, []
        for s in steps:
            if s.kind == StepKind.GRIP:
                carried = True
            elif s.kind == StepKind.RELEASE:
                carried = False
            elif carried and s.kind in MOTION_KINDS:
                out.append(s.index)
        return out
    return [s.index for s in steps if s.kind in MOTION_KINDS]


@dataclass
class ShiftJob:
    """One job of the shift: its number (1-based), params, faults, start (s) and timeline."""

    number: int
    params: dict[str, Any]
    faults: Drawn
    start_s: float
    timeline: Timeline


@dataclass
class ShiftReport:
    """The shift's figures (see the module docstring for their definitions)."""

    plan: ShiftPlan
    jobs: list[ShiftJob]
    downtime_s: float
    rehearsed: int  # distinct jobs the twin rehearsed
    wall_s: float
    first_failures: dict[str, ShiftJob]  # failure kind -> the first job of it

    @property
    def failures(self) -> int:
        return sum(1 for j in self.jobs if j.timeline.stops_the_line)

    @property
    def parts_good(self) -> int:
        return sum(1 for j in self.jobs if j.timeline.ok)

    @property
    def availability(self) -> float:
        return max(0.0, 1.0 - self.downtime_s / self.plan.duration_s)

    @property
    def mtbf_s(self) -> float | None:
        up_s = self.plan.duration_s - self.downtime_s
        return up_s / self.failures if self.failures else None

    @property
    def mttr_s(self) -> float | None:
        return self.downtime_s / self.failures if self.failures else None

    def results(self) -> dict[str, int]:
        counts = Counter(j.timeline.code for j in self.jobs)
        return {str(code): counts[code] for code in sorted(counts)}

    def slowest_steps(self, n: int = SLOWEST_STEPS) -> list[dict[str, Any]]:
        """The steps that took longest on average over the shift's jobs: kind, name, mean
        and max duration (s), how many times they ran."""
        total: dict[tuple[str, str], list[float]] = {}
        for job in self.jobs:
            for kind, name, duration_s in job.timeline.steps:
                total.setdefault((kind, name), []).append(duration_s)
        rows: list[dict[str, Any]] = [
            {
                "kind": kind,
                "name": name,
                "mean_s": round(sum(d) / len(d), 3),
                "max_s": round(max(d), 3),
                "runs": len(d),
            }
            for (kind, name), d in total.items()
        ]
        return sorted(rows, key=lambda r: (-float(r["mean_s"]), str(r["name"])))[:n]

    def to_json(self, replay: Callable[[ShiftJob], str]) -> dict[str, Any]:
        """The ``--json`` object; ``replay`` writes a job's command line."""
        hours = self.plan.duration_s / 3600.0
        recovered = sum(1 for j in self.jobs if j.faults and j.timeline.ok)
        return {
            "ok": True,
            "shift_s": self.plan.duration_s,
            "seed": self.plan.seed,
            "rates": dict(self.plan.rates),
            "jobs": len(self.jobs),
            "parts_good": self.parts_good,
            "parts_bad": len(self.jobs) - self.parts_good,
            "parts_per_hour": round(self.parts_good / hours, 1),
            "availability": round(self.availability, 4),
            "mtbf_s": None if self.mtbf_s is None else round(self.mtbf_s, 1),
            "mttr_s": None if self.mttr_s is None else round(self.mttr_s, 1),
            "failures": self.failures,
            "recovered": recovered,
            "faults_drawn": dict(
                sorted(Counter(f for j in self.jobs for f, _ in j.faults).items())
            ),
            "results": self.results(),
            "downtime_s": round(self.downtime_s, 1),
            "slowest_steps": self.slowest_steps(),
            "replay": [
                {
                    "kind": kind,
                    "job": job.number,
                    "params": job.params,
                    "seed": self.plan.seed,
                    "inject": [f"{f}@{i}" for f, i in job.faults],
                    "result_code": job.timeline.code,
                    "result_text": job.timeline.result_text,
                    "command": replay(job),
                }
                for kind, job in self.first_failures.items()
            ],
            "rehearsed_jobs": self.rehearsed,
            "wall_s": round(self.wall_s, 1),
        }


class ShiftRehearsal:
    """Runs a :class:`ShiftPlan`: ``rehearse_clean(slots)`` gives the fault-free timeline
    of each slot's job (one twin, in order); ``rehearse_faulted(params, drawn)`` one job
    with faults from a fresh twin; ``steps_of(params)`` a job's expanded steps."""

    def __init__(
        self,
        plan: ShiftPlan,
        slots: Sequence[dict[str, Any]],
        steps_of: Callable[[dict[str, Any]], Sequence[Step]],
        rehearse_clean: Callable[[Sequence[dict[str, Any]]], list[Timeline]],
        rehearse_faulted: Callable[[dict[str, Any], Drawn], Timeline],
    ) -> None:
        if plan.duration_s <= 0:
            raise InternalError(f"a shift of {plan.duration_s:g} s: give a duration above 0")
        self.plan, self.slots = plan, list(slots)
        self.steps_of = steps_of
        self.rehearse_clean, self.rehearse_faulted = rehearse_clean, rehearse_faulted
        self._cache: dict[tuple[int, Drawn], Timeline] = {}
        self._steps: dict[int, Sequence[Step]] = {}

    def run(
        self,
        progress: Callable[[float], None] | None = None,
        stop: Callable[[], bool] = lambda: False,
    ) -> ShiftReport:
        """The whole shift; ``progress(simulated s)`` after each job; ``stop()`` true ends
        it early (the report covers the jobs so far)."""
        t_wall = time.perf_counter()
        plan = self.plan
        rng = random.Random(plan.seed)
        clean = self.rehearse_clean(self.slots)
        for i, timeline in enumerate(clean):
            self._cache[(i, ())] = timeline
        rehearsed = len(clean)
        jobs: list[ShiftJob] = []
        first: dict[str, ShiftJob] = {}
        now_s = downtime_s = 0.0
        slot = 0
        while now_s < plan.duration_s and not stop():
            if plan.feed_every_s > 0:  # the job waits for its part
                now_s = max(now_s, len(jobs) * plan.feed_every_s)
                if now_s >= plan.duration_s:
                    break
            params = self.slots[slot]
            drawn = draw_faults(rng, plan.rates, self._steps_for(slot))
            key = (slot, drawn)
            if key not in self._cache:
                self._cache[key] = self.rehearse_faulted(params, drawn)
                rehearsed += 1
            timeline = self._cache[key]
            job = ShiftJob(len(jobs) + 1, params, drawn, now_s, timeline)
            jobs.append(job)
            now_s += timeline.cycle_s
            if timeline.ok:
                slot = (slot + 1) % len(self.slots)  # a full pattern: an empty pallet
            else:
                first.setdefault(failure_kind(job), job)
            if timeline.stops_the_line:
                downtime_s += timeline.cycle_s + plan.operator_s
                now_s += plan.operator_s
            if progress is not None:
                progress(min(now_s, plan.duration_s))
        # a failure whose downtime runs past the end counts only within the shift
        downtime_s = min(downtime_s, plan.duration_s)
        return ShiftReport(plan, jobs, downtime_s, rehearsed, time.perf_counter() - t_wall, first)

    def _steps_for(self, slot: int) -> Sequence[Step]:
        if slot not in self._steps:
            self._steps[slot] = self.steps_of(self.slots[slot])
        return self._steps[slot]


def failure_kind(job: ShiftJob) -> str:
    """A failed job's kind for the replay list: its faults and its result code."""
    faults = "+".join(f for f, _ in job.faults) or "no fault"
    return f"{faults} -> {job.timeline.code}"


def parse_duration(text: str) -> float:
    """``8h``, ``90m``, ``45s``, ``1h30m`` or plain seconds: the duration in s; a
    :class:`~cellrunner.errors.UsageError` naming the forms otherwise."""
    units = {"h": 3600.0, "m": 60.0, "s": 1.0}
    rest, total = text.strip().lower(), 0.0
    if not rest:
        raise UsageError("an empty duration: write 8h, 90m, 45s, 1h30m or seconds")
    try:
        seconds: float | None = float(rest)
    except ValueError:  # float()'s own: not plain seconds, so read the units below
        seconds = None
    if seconds is not None and math.isfinite(seconds) and seconds > 0:
        return seconds
    number = ""
    for ch in rest:
        if ch.isdigit() or ch == ".":
            number += ch
        elif ch in units and number:
            total += float(number) * units[ch]
            number = ""
        else:
            number = "!"
            break
    if number:
        raise UsageError(f"duration {text!r}: write 8h, 90m, 45s, 1h30m or seconds")
    return _positive(total, text)


def _positive(value_s: float, text: str) -> float:
    if not math.isfinite(value_s) or value_s <= 0:
        raise UsageError(f"duration {text!r}: give a time above 0 (8h, 90m, 45s)")
    return value_s
