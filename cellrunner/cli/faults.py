"""``--inject FAULT@STEP``: which fault, and at which expanded step."""

from __future__ import annotations

import re
from dataclasses import dataclass

from cellrunner.errors import UsageError
from cellrunner.execution.shift import SHIFT_FAULTS
from cellrunner.model.expand import Step

#: the shift's faults, and in a watched cell a box dropped onto the step's path (SPEC 12)
FAULTS = (*SHIFT_FAULTS, "intrusion")
#: faults that strike a while into their step (a stop in the middle of a move), not at its start
DELAYED_S = {
    "protective_stop": 0.3,
    "estop": 0.3,
    "robot_disconnect": 0.3,
    "plc_disconnect": 0.3,
    "intrusion": 0.1,
}


@dataclass(frozen=True)
class Injection:
    fault: str
    step_index: int
    spec: str

    @property
    def delay_s(self) -> float:
        return DELAYED_S.get(self.fault, 0.0)

    def delay_within_s(self, step_s: float | None) -> float:
        """When the fault strikes after its step starts: ``delay_s``, or halfway through a
        motion shorter than twice that (``step_s``, its planned duration), so that it
        strikes in its own step, not in the next one."""
        if step_s is None or step_s <= 0.0:
            return self.delay_s
        return min(self.delay_s, 0.5 * step_s)


def parse_injections(specs: list[str], steps: list[Step]) -> list[Injection]:
    """Resolve ``FAULT@STEP`` (STEP: an expanded index, a kind, or ``KIND#N``)."""
    out = []
    for spec in specs:
        fault, _, where = spec.partition("@")
        if fault not in FAULTS:
            raise UsageError(
                f"--inject {spec!r}: unknown fault {fault!r}; known: {', '.join(FAULTS)}"
            )
        if not where:
            raise UsageError(
                f"--inject {spec!r}: write FAULT@STEP (a step index, a kind, or KIND#N)"
            )
        out.append(Injection(fault, _step_index(spec, where, steps), spec))
    return out


def _step_index(spec: str, where: str, steps: list[Step]) -> int:
    if where.isdigit():
        index = int(where)
        if not 1 <= index <= len(steps):
            raise UsageError(
                f"--inject {spec!r}: step {index} does not exist; the task has steps 1..{len(steps)}"
            )
        return index
    m = re.fullmatch(r"([a-z_]+)(?:#(\d+))?", where)
    kinds = list(dict.fromkeys(s.kind for s in steps))
    if not m or m.group(1) not in kinds:
        raise UsageError(
            f"--inject {spec!r}: no step {where!r}; kinds in this task: {', '.join(kinds)}"
        )
    matches = [s for s in steps if s.kind == m.group(1)]
    n = int(m.group(2) or 1)
    if not 1 <= n <= len(matches):
        raise UsageError(f"--inject {spec!r}: the task has {len(matches)} {m.group(1)} step(s)")
    return matches[n - 1].index
