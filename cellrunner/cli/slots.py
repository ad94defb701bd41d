"""Whole runs (SPEC section 12): ``dry-run --slots all`` or ``-p slot=3..8`` names the
values of one integer param, one job per value, run in order in one twin."""

from __future__ import annotations

from cellrunner.errors import UsageError
from cellrunner.model.expand import pattern_params
from cellrunner.model.load import LoadedTask


def whole_run(
    slots: str | None, pairs: list[str], task: LoadedTask
) -> tuple[list[str], tuple[str, list[int]] | None]:
    """The ``-p`` pairs without a range, and the param a whole run steps through with its
    values (None: one job). ``slots`` is ``all``, ``A..B`` or one value, of the param that
    indexes the task's pattern."""
    ranges = [p for p in pairs if ".." in p.partition("=")[2]]
    rest = [p for p in pairs if p not in ranges]
    if slots is None and not ranges:
        return rest, None
    if len(ranges) + (slots is not None) > 1:
        raise UsageError("one whole run at a time: give --slots or one -p NAME=A..B")
    if slots is not None:
        name = _slot_param(task)
        text = slots
    else:
        name, _, text = ranges[0].partition("=")
        name = name.strip()
    param = task.task.params.get(name)
    if param is None or param.type != "int" or param.min is None or param.max is None:
        known = [n for n, p in task.task.params.items() if p.type == "int"]
        raise UsageError(
            f"-p {name}=...: a range needs an integer param of the task with min and max; "
            f"known: {', '.join(known) or '(none)'}"
        )
    lo, hi = int(param.min), int(param.max)
    if text.strip() == "all":
        return rest, (name, list(range(lo, hi + 1)))
    first, sep, last = text.partition("..")
    try:
        a, b = int(first), int(last) if sep else int(first)
    except ValueError:
        raise UsageError(
            f"{name}={text!r}: write all, a value, or FIRST..LAST (within {lo}..{hi})"
        ) from None
    if not lo <= a <= b <= hi:
        raise UsageError(f"{name}={text}: the values must rise within {lo}..{hi}")
    return rest, (name, list(range(a, b + 1)))


def _slot_param(task: LoadedTask) -> str:
    """The param of the task's patterns (``--slots`` steps through it)."""
    names = list(pattern_params(task))
    if len(names) != 1:
        found = ", ".join(names) or "none"
        raise UsageError(
            f"--slots needs a task with one pattern param (found: {found}); "
            "write -p NAME=FIRST..LAST instead"
        )
    return names[0]
