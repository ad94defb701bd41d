"""The plans of one cell by key, in memory and on disk; the world holds one
(:attr:`CellWorld.plans <cellrunner.planning.world.CellWorld.plans>`).

A key (:func:`~cellrunner.planning.job_plan.plan_key`) is made of everything a plan
depends on: the cell, task and mesh files' digests, the params, the start configuration
and the code that plans (planning, model and the step kinds, ``PLAN_SOURCES``). A repeated job reuses its approved trajectories without
planning; any change to the files misses. The store knows files only as paths: reading
and writing a plan is :mod:`.plan_files`'s.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any


class PlanStore:
    """Plans by key: in memory for ``serve``, and as files under ``directory``.

    Memory keeps at most ``MEMORY_MAX`` plans, least recently used first. A job that
    starts where a fault left the arm has a plan of its own that is rarely used again;
    with a bound of 64 those (~0.5 MB each) grew serve's memory by 10 % over 250 soak jobs
    (bench_plc). So a plan is kept from its second use on (the first repeat reads it from
    disk): keys asked for once are remembered, oldest out, and one-off plans never take
    the place of the ones in use."""

    MEMORY_MAX = 16
    ASKED_ONCE_MAX = 1024

    def __init__(self, directory: Path) -> None:
        self.directory = directory
        self.memory: dict[str, Any] = {}
        self._asked_once: dict[str, None] = {}

    def path(self, key: str) -> Path:
        return self.directory / f"{key}.npz"

    def has(self, key: str) -> bool:
        """Whether the plan of ``key`` is stored (in memory or on disk)."""
        return key in self.memory or self.path(key).is_file()

    def get(self, key: str, read: Callable[[Path], Any]) -> Any:
        """The plan of ``key`` from memory, else ``read(path)`` of its file (None when
        there is none or it cannot be read)."""
        plan = self.memory.get(key)
        if plan is not None:
            self.memory[key] = self.memory.pop(key)  # the most recently used goes last
            return plan
        path = self.path(key)
        plan = read(path) if path.is_file() else None
        if plan is not None:
            self._keep(key, plan)
        return plan

    def put(self, key: str, plan: Any, write: Callable[[Path], None] | None) -> None:
        """Keep ``plan``; ``write(path)`` puts it on disk (None: memory only)."""
        if write is not None:
            write(self.path(key))
        self._keep(key, plan)

    def _keep(self, key: str, plan: Any) -> None:
        """Keep ``plan`` in memory if ``key`` was asked for before."""
        if key not in self._asked_once:
            while len(self._asked_once) >= self.ASKED_ONCE_MAX:
                self._asked_once.pop(next(iter(self._asked_once)))
            self._asked_once[key] = None
            return
        del self._asked_once[key]
        self.memory.pop(key, None)
        while len(self.memory) >= self.MEMORY_MAX:
            self.memory.pop(next(iter(self.memory)))  # the least recently used
        self.memory[key] = plan
