"""The expanded steps of one job, made once per process and shared.

A job's steps (:func:`~cellrunner.model.expand.expand` of a task for its resolved params)
are needed by whoever meets the job: the plan, the twin's description (the parts a task
picks, the earlier slots, the fed part), the rehearsal's progress and report. They all
take them from :func:`job_steps`, which expands a (task, cell, params) once and hands
the same :class:`~cellrunner.model.step.Step` objects (frozen) to every later caller.

The memo is keyed by the loaded task and cell objects themselves (a file loaded again is
another object, so never a stale expansion) and the params; it keeps the few most recent
jobs only.
"""

from __future__ import annotations

import json
import threading
from collections import OrderedDict
from collections.abc import Mapping
from typing import Any

from cellrunner.model import expand as _expand
from cellrunner.model.cell import Cell
from cellrunner.model.loaded import LoadedTask
from cellrunner.model.step import Step

#: this many recent jobs keep their expanded steps
KEPT_JOBS = 64

_Key = tuple[int, int, str]
# key -> (task, cell, steps): the task and cell are held so that their ids stay theirs
_memo: OrderedDict[_Key, tuple[LoadedTask, Cell, tuple[Step, ...]]] = OrderedDict()
_lock = threading.Lock()


def job_steps(task: LoadedTask, cell: Cell, params: Mapping[str, Any]) -> list[Step]:
    """The primitive steps of ``task`` on ``cell`` for ``params`` (resolved), expanded
    the first time this job is met and shared afterwards (a new list of the same steps)."""
    key = (id(task), id(cell), json.dumps(dict(params), sort_keys=True, default=repr))
    with _lock:
        found = _memo.get(key)
        if found is not None:
            _memo.move_to_end(key)
            return list(found[2])
    steps = tuple(_expand.expand(task, cell, dict(params)))
    with _lock:
        _memo[key] = (task, cell, steps)
        while len(_memo) > KEPT_JOBS:
            _memo.popitem(last=False)
    return list(steps)
