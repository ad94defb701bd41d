"""What ``check`` reports, as data: the requested job's plan, the values its params were
checked at, and the failures grouped.

Failures of a pattern's slots are grouped by what they are (:meth:`Failure.key`: the
kind of refusal, the step and the bodies in the way), never by their text: slots 3-5
refused at the same step by the same fixture are one entry, shown with the first slot's
failure. A pose, float or frame param's failing values are each their own entry. The
text is made from the fields here and in the CLI's printer, the edge.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from cellrunner.model.expand import ALIGN_KEY, pattern_params
from cellrunner.model.failure import Failure
from cellrunner.model.load import LoadedTask
from cellrunner.model.params import ParamValue

if TYPE_CHECKING:
    from cellrunner.execution.slot_sweep import Sweep
    from cellrunner.planning.job_plan import JobPlan
    from cellrunner.planning.tracking import TrackingProof


@dataclass(frozen=True)
class FailedValues:
    """Values of param ``param`` that fail the same way: ``failure`` is the first one's."""

    param: str
    values: list[ParamValue]
    failure: Failure

    @property
    def where(self) -> str:
        """'slots 3-5, 9', 'slot=3', 'pose={...}': the values, as messages name them."""
        slots = [v for v in self.values if isinstance(v, int) and not isinstance(v, bool)]
        if len(slots) == len(self.values):
            return slot_range_text(self.param, slots)
        return ", ".join(f"{self.param}={shown(v)}" for v in self.values)

    def lines(self) -> list[str]:
        """The failure one clause per line, the values in front of the first."""
        first, *rest = self.failure.lines()
        return [f"{self.where}: {first}", *rest]

    def text(self) -> str:
        return "; ".join(self.lines())

    def to_json(self) -> dict[str, Any]:
        """One of ``check --json``'s ``failed_slots``: ``param``, ``slots``, ``error`` (the
        text), ``kind``, ``step`` (its index) and ``blockers`` (kind, name, distance)."""
        f = self.failure
        return {
            "param": self.param,
            "slots": self.values,
            "error": f.text(),
            "kind": f.kind.value,
            "step": f.step_index,
            "blockers": [
                {"kind": b.body.kind.value, "name": b.body.name, "distance_m": b.distance_m}
                for b in f.blockers
            ],
        }


@dataclass(frozen=True)
class CheckReport:
    """The requested job's ``plan`` (its ``params``), every value checked per param, and
    the failures: ``found`` each other value's as the sweep found them, ``slots`` grouped
    (a pattern's), ``values`` one each (a pose's, a float's, a frame's), ``bare`` the
    requested plan's own when the task has no pattern."""

    plan: JobPlan
    params: dict[str, ParamValue]
    checked: dict[str, list[ParamValue]]
    found: list[FailedValues]
    slots: list[FailedValues]
    values: list[FailedValues]
    bare: list[Failure]
    tracking: list[TrackingProof] = field(default_factory=list)

    @property
    def errors(self) -> list[str]:
        """Every failure on one line: the requested plan's, then each other value's, then
        the conveyors'."""
        return [
            *self.plan.errors,
            *(f"{g.param}={shown(g.values[0])}: {g.failure.text()}" for g in self.found),
            *(p.error for p in self.tracking if p.error is not None),
        ]

    @property
    def ok(self) -> bool:
        return not self.errors

    def rows(self) -> list[dict[str, Any]]:
        """The plan's rows (the on_error rows last: verified from every state)."""
        return [
            {
                "index": r.step.index,
                "name": r.step.name,
                "kind": r.step.kind,
                "duration_s": round(r.duration_s, 4),
                "status": r.status,
                "message": r.message,
                "attempts": 0,
            }
            for r in self.plan.rows
        ]

    def checked_lines(self) -> list[str]:
        """What was checked, one line per param."""
        return [_checked_line(name, values) for name, values in self.checked.items()]


def check_report(
    swept: Sweep,
    task: LoadedTask,
    params: dict[str, ParamValue],
    tracking: list[TrackingProof] | None = None,
) -> CheckReport:
    """``swept`` (the requested plan and every other value's failures) and the conveyors'
    ``tracking`` proofs as a report."""
    plan = swept.plan
    pattern = next(iter(pattern_params(task)), None)
    found = [(f.param, f.value, f.failure) for f in swept.failures]
    each = _once(
        [
            (name, value, f)
            for name, value, f in found
            if (isinstance(value, int) and not isinstance(value, bool)) or f not in plan.failures
        ]
    )
    requested = (
        [(pattern, params[pattern], f) for f in plan.failures] if pattern is not None else []
    )
    slots = group_failures(
        [
            (name, value, f)
            for name, value, f in requested + found
            if isinstance(value, int) and not isinstance(value, bool)
        ]
    )
    # pose, float and frame params: each failing value on its own
    values = _once(
        [
            (name, value, f)
            for name, value, f in found
            if isinstance(value, (dict, float, str)) and f not in plan.failures
        ]
    )
    bare = list(plan.failures) if pattern is None else []
    return CheckReport(plan, params, swept.checked, each, slots, values, bare, tracking or [])


def _once(failures: list[tuple[str, ParamValue, Failure]]) -> list[FailedValues]:
    """Each failing value on its own, except that one failure, equal in every field
    (text included), for several values of a param is one cause, shown once with them
    all (an align's camera that cannot read its marker fails every correction alike);
    the requested plan's own failures are left out by the caller."""
    groups: dict[tuple[str, Failure], list[ParamValue]] = {}
    for name, value, failure in failures:
        groups.setdefault((name, failure), []).append(value)
    return [FailedValues(name, values, f) for (name, f), values in groups.items()]


def group_failures(failures: list[tuple[str, int, Failure]]) -> list[FailedValues]:
    """Slot failures grouped per param by :meth:`Failure.key` (kind, step, bodies in the
    way), in first-seen order, each shown with its first failure; the slots sorted."""
    groups: dict[tuple[str, tuple[object, ...]], tuple[set[int], Failure]] = {}
    for name, slot, failure in failures:
        groups.setdefault((name, failure.key()), (set(), failure))[0].add(slot)
    return [
        FailedValues(name, [*sorted(slots)], failure)
        for (name, _), (slots, failure) in groups.items()
    ]


def slot_range_text(name: str, slots: list[int]) -> str:
    """``slot``, [3, 4, 5, 9] -> 'slots 3-5, 9' (one slot: 'slot=3'; another param: 'k 3-5, 9')."""
    if len(slots) == 1:
        return f"{name}={slots[0]}"
    runs: list[list[int]] = []
    for s in sorted(slots):
        if runs and s == runs[-1][-1] + 1:
            runs[-1].append(s)
        else:
            runs.append([s])
    text = ", ".join(f"{r[0]}-{r[-1]}" if len(r) > 1 else str(r[0]) for r in runs)
    return f"{'slots' if name == 'slot' else name} {text}"


def shown(value: object) -> str:
    """A param value as messages write it (a pose as compact JSON)."""
    if isinstance(value, dict):
        return json.dumps(value, separators=(",", ":"))
    return str(value)


def _checked_line(name: str, values: list[ParamValue]) -> str:
    if name.startswith(ALIGN_KEY):
        return (
            f"align {name.removeprefix(ALIGN_KEY)}: {len(values)} corrections checked "
            "(its max_correction box's centre and corners)"
        )
    if isinstance(values[0], dict):
        return f"pose param {name}: {len(values)} poses checked (its box's centre and corners)"
    if isinstance(values[0], str):
        return f"frame param {name}: {', '.join(str(v) for v in values)} checked (every choice)"
    if isinstance(values[0], float):
        return (
            f"float param {name}: {', '.join(f'{v:g}' for v in values)} checked "
            "(its range's ends and centre)"
        )
    return f"pattern param {name}: {len(values)} slots checked ({values[0]}..{values[-1]})"
