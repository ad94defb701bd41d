"""The twin's moves built from program statements: one movej/movel, or a path run in sequence."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from cellrunner.twin import motion as mo
from cellrunner.twin.controller import Controller
from cellrunner.twin.kinematics import pose_to_matrix
from cellrunner.twin.script_text import PathEntry


@dataclass
class Sequence:
    """Run motions one after another; each is built when the previous one ends."""

    factories: list[Callable[[np.ndarray], Any]]
    progress_of: list[list[int]]
    current: Any = None
    index: int = -1

    def advance(
        self, q: np.ndarray, qd: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray, bool]:
        if self.current is None:
            self.index += 1
            self.current = self.factories[self.index](q)
        q, qd, done = self.current.advance(q, qd, dt)
        if done:
            self.current = None
            return q, qd, self.index == len(self.factories) - 1
        return q, qd, False

    @property
    def progress(self) -> int:
        if self.index < 0:
            return self.progress_of[0][0] if self.progress_of and self.progress_of[0] else 0
        group = self.progress_of[self.index]
        seg = (
            getattr(self.current, "segment_index", len(group) - 1)
            if self.current is not None
            else len(group) - 1
        )
        return group[min(seg, len(group) - 1)]


def build_path_motion(ctl: Controller, entries: list[PathEntry]) -> Sequence:
    """Group consecutive movej / movel entries into blended paths, run in sequence."""
    groups: list[list[PathEntry]] = []
    for entry in entries:
        if groups and groups[-1][0].kind == entry.kind:
            groups[-1].append(entry)
        else:
            groups.append([entry])
    factories = [_path_factory(ctl, group) for group in groups]
    return Sequence(factories, [[e.progress for e in g] for g in groups])


def _path_factory(ctl: Controller, group: list[PathEntry]) -> Callable[[np.ndarray], Any]:
    def make(q_start: np.ndarray) -> Any:
        waypoints = []
        q_seed = q_start
        for e in group:
            target = np.array(e.target)
            if e.kind == "movej":
                if e.is_pose:
                    q_ik = ctl.kinematics.inverse(pose_to_matrix(target), q_seed)
                    if q_ik is None:
                        raise mo.MotionError(
                            f"movej: no inverse kinematics solution for p{list(e.target)}"
                        )
                    target = q_ik
                q_seed = target
            elif not e.is_pose:
                target = ctl.kinematics.tcp_pose(target)
            waypoints.append((target, e.v, e.a, e.r))
        cls = mo.JointPath if group[0].kind == "movej" else mo.LinearPath
        return cls(q_start, waypoints, ctl.kinematics, ctl.qd_max, ctl.speed_slider)

    return make


def movej(ctl: Controller, q: np.ndarray, v: float, a: float) -> mo.JointPath:
    return mo.JointPath(
        ctl.target_q,
        [(np.asarray(q, float), v, a, 0.0)],
        ctl.kinematics,
        ctl.qd_max,
        ctl.speed_slider,
    )


def movel(ctl: Controller, pose: np.ndarray, v: float, a: float) -> mo.LinearPath:
    return mo.LinearPath(
        ctl.target_q,
        [(np.asarray(pose, float), v, a, 0.0)],
        ctl.kinematics,
        ctl.qd_max,
        ctl.speed_slider,
    )
