"""The parts a whole run needs (SPEC section 12): a new part fed at its frame before each
job, and the parts of the earlier slots of a pattern already in place.

- ``sim: {feed: {part, at}}``: copies of the part wait parked far outside the cell
  (floating, touching nothing, out of every camera's range); before each job (:meth:`Feeder.feed`) one is
  put at the frame, as a part ``at:`` it lies, unless a part already lies there. In the
  virtual controller, which knows no jobs, :meth:`Feeder.update` feeds once the part fed
  last was taken away (gripped and gone): a part knocked off by ``grip_miss`` is not
  replaced. When every copy is out, the oldest one not held is fed again (the line took
  the finished load away).
- A rehearsal of slot N of a place pattern starts with a part on every earlier slot, where
  the task would have put it (:func:`earlier_slots`): slot 7 of a 2-layer pallet is
  stacked on the first layer, not dropped onto an empty pallet.

Both are more parts in the :class:`~.description.TwinDescription` (a MuJoCo model cannot
grow), made by :func:`with_rehearsal_parts`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from cellrunner.model.geometry import Box, Cylinder, Shape, Sphere
from cellrunner.sim.mjcf_attrs import PART_HITS, PARTS

if TYPE_CHECKING:
    from cellrunner.model.loaded import LoadedCell, LoadedTask
    from cellrunner.sim.description import PartDescription, TwinDescription
    from cellrunner.sim.model_ids import ModelIds

PARK_X_M = 200.0  # parked copies lie on the floor this far out along world X ...
PARK_PITCH_M = 2.0  # ... this far apart along Y
SAME_PLACE_M = 0.01  # a part this close to a slot's target already fills it


@dataclass(frozen=True)
class FeedDescription:
    """Copies ``copies`` (part names in the description) of one part, fed at
    ``T_world_part``; the spot counts as taken while a part's centre is within
    ``within_m`` of it."""

    part: str
    T_world_part: np.ndarray
    copies: tuple[str, ...]
    within_m: float
    #: a conveyor's feed (``sim: feed: {conveyor, every, jitter}``): a part every
    #: ``every_s`` of the twin's time, each off its even spacing by up to ``jitter_m``
    #: along ``along`` (the belt's direction at the spot, world) whose speed is
    #: ``speed_mps``; drawn from a generator seeded with ``seed``
    every_s: float | None = None
    jitter_m: float = 0.0
    along: tuple[float, float, float] = (0.0, 0.0, 0.0)
    speed_mps: float = 0.0
    seed: int = 0


def copy_name(part: str, k: int) -> str:
    return f"{part}#{k}"


def slot_name(part: str, param: str, value: int) -> str:
    return f"{part}@{param}={value}"


def with_rehearsal_parts(
    desc: TwinDescription,
    feed: tuple[str, np.ndarray] | None = None,
    copies: int = 0,
    placed: Sequence[tuple[str, str, np.ndarray]] = (),
) -> TwinDescription:
    """``desc`` with ``copies`` parked copies of the part named ``feed[0]`` to be fed at
    ``feed[1]`` (T_world_part), and parts ``(name, copy of, T_world_part)`` in place."""
    parts = {p.name: p for p in desc.parts}
    extra: list[PartDescription] = [
        dataclasses.replace(parts[of], name=name, T_world_part=np.array(T))
        for name, of, T in placed
    ]
    feed_desc = desc.feed
    if feed is not None and copies > 0:
        part, T_fed = feed
        names = tuple(copy_name(part, k + 1) for k in range(copies))
        extra += [
            dataclasses.replace(parts[part], name=n, T_world_part=_parked(parts[part].shape, k))
            for k, n in enumerate(names)
        ]
        feed_desc = FeedDescription(part, np.array(T_fed), names, _spot_m(parts[part].shape))
    return dataclasses.replace(desc, parts=(*desc.parts, *extra), feed=feed_desc)


def feed_of(loaded: LoadedCell, task: LoadedTask | None, whole_run: bool) -> tuple[str, str] | None:
    """(part, frame) fed before each job: the cell's ``sim: feed``; in a whole run without
    one, the part the task picks first, at its frame (a run of many jobs needs a part for
    each)."""
    sim = loaded.cell.sim
    if sim is not None and sim.feed is not None:
        return sim.feed.part, sim.feed.frame(loaded.cell.conveyors)
    if not whole_run or task is None:
        return None
    from cellrunner.model.expand import resolve_params
    from cellrunner.model.job_steps import job_steps

    steps = job_steps(task, loaded.cell, resolve_params(task.task, {}))
    for step in steps:
        frame = step.extra.get("part_at")
        if isinstance(frame, str):
            part = next((p.name for p in loaded.cell.parts if p.at == frame), None)
            if part is not None:
                return part, frame
    return None


def earlier_slots(
    loaded: LoadedCell,
    task: LoadedTask,
    params: dict[str, Any],
    desc: TwinDescription,
) -> list[tuple[str, str, np.ndarray]]:
    """The parts on the slots of each place pattern below its value in ``params``
    (resolved), where the task puts them: ``(name, copy of, T_world_part)``. A slot a part
    of the cell file already fills is left as it is."""
    from cellrunner.model.job_steps import job_steps
    from cellrunner.model.step import StepKind

    places = [s for s in task.steps if s.kind == StepKind.PLACE]
    grips = {p.name: np.asarray(p.T_grip_part) for p in desc.parts}
    lying = [np.asarray(p.T_world_part)[:3, 3] for p in desc.parts]
    out: list[tuple[str, str, np.ndarray]] = []
    for param, spec in task.task.params.items():
        patterned = [
            i
            for i, s in enumerate(places)
            if getattr(s.args, "pattern", None) is not None and s.args.pattern.index == param
        ]
        if not patterned:
            continue
        for value in range(int(spec.min), int(params[param])):
            steps = job_steps(task, loaded.cell, {**params, param: value})
            for i, (part, T_world_tcp) in enumerate(_places(loaded, steps)):
                if i not in patterned or part is None:
                    continue
                T = T_world_tcp @ grips[part]
                if any(np.linalg.norm(p - T[:3, 3]) < SAME_PLACE_M for p in lying):
                    continue
                lying.append(T[:3, 3])
                out.append((slot_name(part, param, value), part, T))
    return out


def _places(loaded: LoadedCell, steps: list[Any]) -> list[tuple[str | None, np.ndarray]]:
    """Each place of the expanded ``steps`` in order: (the part picked before it, or None;
    the TCP's target)."""
    out: list[tuple[str | None, np.ndarray]] = []
    carried: str | None = None
    for step in steps:
        frame = step.extra.get("part_at")
        if isinstance(frame, str):
            carried = next((p.name for p in loaded.cell.parts if p.at == frame), None)
        check = step.extra.get("place_check")
        if check is not None:
            out.append((carried, np.asarray(check["T_world_tcp"])))
    return out


def _half_height_m(shape: Shape) -> float:
    if isinstance(shape, Box):
        return float(shape.size_m[2]) / 2
    if isinstance(shape, Cylinder):
        return float(shape.length_m) / 2
    if isinstance(shape, Sphere):
        return float(shape.radius_m)
    return 0.1


def _spot_m(shape: Shape) -> float:
    """How near a part's centre must lie to the feed spot to take it: half the shape's
    smallest width (two parts cannot be nearer), at least 1 cm."""
    if isinstance(shape, Box):
        return max(0.01, float(min(shape.size_m[0], shape.size_m[1])) / 2)
    if isinstance(shape, Cylinder | Sphere):
        return max(0.01, float(shape.radius_m))
    return 0.02


def _parked(shape: Shape, k: int) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (PARK_X_M, PARK_PITCH_M * k, _half_height_m(shape) + 0.001)
    return T


class FeedWorld(Protocol):
    """What the feed moves in the twin (:class:`~cellrunner.sim.world.SimWorld`)."""

    model: Any
    data: Any

    @property
    def mujoco(self) -> Any: ...

    @property
    def ids(self) -> ModelIds: ...

    @property
    def gripped(self) -> frozenset[str]: ...

    @property
    def time_s(self) -> float: ...

    def contacts_changed(self) -> None: ...


class Feeder:
    """The feed of one built :class:`SimWorld` (its description's ``feed``)."""

    def __init__(self, world: FeedWorld, feed: FeedDescription) -> None:
        self.world, self.desc = world, feed
        self.parked = list(feed.copies)
        self.fed: list[str] = []  # oldest first
        self._at_spot: str | None = self._lying_at_spot()
        self._taken = False
        self._rng = np.random.default_rng(feed.seed)
        # the first fed part follows the parts the cell file lays on the belt
        self._due_s = feed.every_s if feed.every_s is not None else float("inf")
        #: (name, twin time s) of each part fed by time, oldest first
        self.timed: list[tuple[str, float]] = []

    def feed(self) -> str | None:
        """Before a job: a copy at the spot unless a part lies there; its name, or None."""
        if self._lying_at_spot() is not None:
            return None
        name = self._next_copy()
        if name is None:
            return None
        self._put(name, self.desc.T_world_part)
        self._at_spot, self._taken = name, False
        return name

    def update(self) -> str | None:
        """Without jobs (the virtual controller): feed once the part at the spot was
        gripped and has left it (a conveyor's feed: once its ``every`` is due); the name
        fed, or None."""
        if self.desc.every_s is not None:
            return self._update_timed(self.desc.every_s)
        gripped = self.world.gripped
        if self._at_spot is not None and self._at_spot in gripped:
            self._taken = True
        if self._taken and not gripped and self._lying_at_spot() is None:
            return self.feed()
        return None

    def _update_timed(self, every_s: float) -> str | None:
        """A conveyor's feed: a part every ``every_s`` of the twin's time, put where an
        even feed would have carried it by now (the update comes late by up to its own
        period) and off that by the jitter; none while the part fed last still lies at
        the spot (the belt stopped)."""
        now = self.world.time_s
        if now < self._due_s or self._lying_at_spot() is not None:
            return None  # not yet, or the last one still lies there (a stopped belt)
        late_s, self._due_s = now - self._due_s, max(self._due_s + every_s, now)
        name = self._next_copy()
        if name is None:
            return None
        jitter = float(self._rng.uniform(-1.0, 1.0)) * self.desc.jitter_m
        T = np.array(self.desc.T_world_part, dtype=float)
        T[:3, 3] += np.asarray(self.desc.along) * (self.desc.speed_mps * late_s + jitter)
        self._put(name, T)
        self.timed.append((name, now))
        return name

    def _lying_at_spot(self) -> str | None:
        w, spot = self.world, self.desc.T_world_part[:3, 3]
        for name, body in w.ids.part_bodies.items():
            if np.linalg.norm(w.data.xpos[body] - spot) < self.desc.within_m:
                return name
        return None

    def _next_copy(self) -> str | None:
        if self.parked:
            name = self.parked.pop(0)
        else:  # every copy is out: the oldest one not held comes back
            held = self.world.gripped
            name = next((n for n in self.fed if n not in held), "")
            if not name:
                return None
            self.fed.remove(name)
        self.fed.append(name)
        return name

    def _put(self, name: str, T_world_part: np.ndarray) -> None:
        from scipy.spatial.transform import Rotation

        w = self.world
        m, d = w.model, w.data
        # parked, it floated touching nothing (gravity compensated, no collisions)
        body = w.ids.part_bodies[name]
        m.body_gravcomp[body] = 0.0
        g = w.ids.part_geom[name]
        m.geom_contype[g], m.geom_conaffinity[g] = PARTS, PART_HITS
        m.body_contype[body], m.body_conaffinity[body] = PARTS, PART_HITS  # (broad phase)
        w.contacts_changed()
        adr = w.ids.part_qpos[name]
        x, y, z, qw = Rotation.from_matrix(T_world_part[:3, :3]).as_quat()
        d.qpos[adr : adr + 7] = [*T_world_part[:3, 3], qw, x, y, z]
        dof = m.jnt_dofadr[m.joint(f"part:{name}").id]
        d.qvel[dof : dof + 6] = 0.0
        w.mujoco.mj_forward(m, d)
