"""Inputs the twin drives from the cell's ``sim:`` rules (SPEC section 11), evaluated
once per controller period on simulated time, so a rehearsal gives the same inputs at
the same instants every time.

- ``part_at``: true while some part's centre lies within ``within_m`` of a point;
- ``follows``: the output's value ``delay_s`` after it was written (a door's end switch);
- ``pulse_after``: true for ``width_s``, ``delay_s`` after the output rose (a machine's
  cycle-done pulse); a rise during a pending pulse restarts it.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass


@dataclass(frozen=True)
class InputRuleDescription:
    """One driven input: ``channel`` and its rule, in channels and world metres."""

    channel: str
    kind: str  # part_at | follows | pulse_after
    output: str | None = None  # output channel (follows, pulse_after)
    point_world_m: tuple[float, float, float] | None = None  # part_at
    within_m: float = 0.02
    delay_s: float = 0.0
    width_s: float = 0.5
    invert: bool = False


class InputRules:
    """The state of every rule: the output history they need, their current values."""

    def __init__(self, rules: tuple[InputRuleDescription, ...]) -> None:
        self.rules = rules
        self._changes: dict[str, list[tuple[float, bool | float]]] = {}  # output -> (t, value)
        self._last: dict[str, bool | float] = {}
        self._rise_s: dict[str, float] = {}  # pulse_after output -> time of its last rise

    def channels(self) -> set[str]:
        return {r.channel for r in self.rules}

    def evaluate(
        self,
        t_s: float,
        outputs: dict[str, bool | float],
        part_positions: Iterable[Sequence[float]],
    ) -> dict[str, bool | float]:
        """The driven inputs at ``t_s`` (s) given the outputs now and the parts' world
        positions (an iterable of 3-sequences in m)."""
        self._note_outputs(t_s, outputs)
        return self._values(t_s, part_positions, prune=True)

    def peek(
        self,
        t_s: float,
        outputs: dict[str, bool | float],
        part_positions: Iterable[Sequence[float]],
    ) -> dict[str, bool | float] | None:
        """What :meth:`evaluate` would return at ``t_s``, without changing any rule's
        state (a look-ahead's question); None when an output changed since its last call
        (then only :meth:`evaluate` can tell)."""
        if any(
            self._last.get(r.output) != outputs.get(r.output, False)
            for r in self.rules
            if r.output is not None
        ):
            return None
        return self._values(t_s, part_positions, prune=False)

    def _note_outputs(self, t_s: float, outputs: dict[str, bool | float]) -> None:
        for rule in self.rules:
            if rule.output is None:
                continue
            value = outputs.get(rule.output, False)
            if self._last.get(rule.output) != value:
                self._changes.setdefault(rule.output, []).append((t_s, value))
                if value and not self._last.get(rule.output):
                    self._rise_s[rule.output] = t_s
                self._last[rule.output] = value

    def _values(
        self, t_s: float, part_positions: Iterable[Sequence[float]], *, prune: bool
    ) -> dict[str, bool | float]:
        positions = None
        out: dict[str, bool | float] = {}
        for rule in self.rules:
            value: bool | float
            if rule.kind == "part_at":
                assert rule.point_world_m is not None  # a part_at rule has its point
                if positions is None:
                    positions = [tuple(p) for p in part_positions]
                value = any(math.dist(p, rule.point_world_m) <= rule.within_m for p in positions)
            elif rule.kind == "follows":
                assert rule.output is not None  # follows and pulse_after name an output
                value = self._value_at(rule.output, t_s - rule.delay_s, prune)
            else:
                assert rule.output is not None
                rose = self._rise_s.get(rule.output)
                value = (
                    rose is not None
                    and rose + rule.delay_s <= t_s < rose + rule.delay_s + rule.width_s
                )
            out[rule.channel] = (not value) if rule.invert and isinstance(value, bool) else value
        return out

    def _value_at(self, output: str, t_s: float, prune: bool = True) -> bool | float:
        changes = self._changes.get(output)
        if not changes:
            return False
        k = -1
        for i, (t, _) in enumerate(changes):
            if t > t_s + 1e-9:
                break
            k = i
        if k < 0:
            return False
        if not prune:
            return changes[k][1]
        del changes[:k]  # older changes can no longer matter (time only moves on)
        return changes[0][1]
