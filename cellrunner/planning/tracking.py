"""``check``'s proof of the steps between ``track`` and ``untrack`` (SPEC section 13).

The steps are planned as usual, for a part standing still at the conveyor's frame: the
relative motion. On the belt the arm commands, at every instant,

    T_world_tcp(t) = T_shift(sigma(t)) @ T_world_tcp_still(t)

with ``sigma`` the belt offset (m along the path): a ramp onto the part (:mod:`.belt_ramp`),
the part's own travel ``d0 + v t`` while the steps run, and a ramp back to the frame. This
module proves that for belt speeds from 0 to ``speed_max`` and parts anywhere the window
allows the pick to start: every commanded pose has an IK solution joined to the last,
the joints keep their speed and acceleration limits x margin (the belt's velocity
included), the TCP its speed cap, and nothing collides with the still cell. It finds the
latest point in the window the pick may start at top speed, the parts per minute the
cell can take, and, when top speed cannot be made, the speed that can.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.model.conveyor import Conveyor, T_world_shift
from cellrunner.planning.belt_ramp import nominal_start_m, ramp_bounds, ramp_in
from cellrunner.planning.tracked_piece import (
    TrackedPiece,
    commanded_offsets,
    still_piece,
    tracked_stretches,
)

if TYPE_CHECKING:
    from cellrunner.planning.task_plan import TaskPlan
    from cellrunner.planning.world import CellWorld

#: the proof samples the commanded motion this often, s
SAMPLE_S = 0.008
#: belt speeds proved, as fractions of speed_max
SPEED_FRACTIONS = (1.0, 0.75, 0.5, 0.25, 0.0)
#: starts proved at each speed, from the earliest to the latest the window allows
START_SAMPLES = 7
#: candidates scanned for the latest start the window allows
START_CANDIDATES = 41
#: points of the window whose reach is measured (the grip pose shifted along it)
REACH_SAMPLES = 45
#: speeds tried, as fractions of speed_max, for the one a refused pick can be made at
SLOWER_FRACTIONS = tuple(round(1.0 - 0.05 * k, 2) for k in range(1, 20))
#: a limit counts as kept within this relative excess (finite differences of the samples)
LIMIT_TOLERANCE = 1e-6


@dataclass(frozen=True)
class CaseResult:
    """One belt speed and one start: proved, or why not."""

    speed_mps: float
    start_m: float
    ok: bool
    reason: str = ""


@dataclass
class TrackingProof:
    """What ``check`` says of one tracked stretch of a task."""

    conveyor: str
    speed_max_mps: float
    window_m: tuple[float, float]
    tracked_s: float
    cycle_s: float
    reachable_m: list[tuple[float, float]] = field(default_factory=list)
    latest_start_m: float | None = None
    speed_ok_mps: float | None = None
    cases: list[CaseResult] = field(default_factory=list)
    #: why the stretch is refused, one clause a line (empty: proved); :attr:`error` joins them
    error_lines: list[str] = field(default_factory=list)
    what: str = "pick"  # what the tracked steps do: a pick, or a place onto the belt

    @property
    def parts_per_minute(self) -> float:
        return 60.0 / self.cycle_s if self.cycle_s > 0 else 0.0

    @property
    def min_pitch_m(self) -> float:
        """The closest parts may follow each other at top speed for the cell to take
        every one, m: the belt's travel in one cycle."""
        return self.speed_max_mps * self.cycle_s

    @property
    def error(self) -> str | None:
        """Why the stretch is refused on one line (None: proved)."""
        return "; ".join(self.error_lines) if self.error_lines else None

    @error.setter
    def error(self, text: str | None) -> None:
        self.error_lines = [] if text is None else [text]

    def summary_lines(self) -> list[str]:
        """What ``check`` prints of the stretch, one clause a line."""
        lo, hi = self.window_m
        reach = ", ".join(f"[{a:+.3f}, {b:+.3f}]" for a, b in self.reachable_m) or "none"
        lines = [
            f"conveyor {self.conveyor}: window [{lo:+.3f}, {hi:+.3f}] m, reachable {reach} m",
            f"{sum(c.ok for c in self.cases)} of {len(self.cases)} cases proved "
            f"(speeds 0-{self.speed_max_mps:g} m/s)",
        ]
        if self.latest_start_m is not None:
            lines += [
                f"at {self.speed_max_mps:g} m/s the {self.what} may start until the part is "
                f"{self.latest_start_m:+.3f} m from the frame",
                f"{self.parts_per_minute:.1f} parts/min at most (cycle {self.cycle_s:.2f} s, "
                f"parts at least {self.min_pitch_m:.3f} m apart)",
            ]
        return lines

    def summary(self) -> str:
        """The stretch on one line."""
        return "; ".join(self.summary_lines())

    def to_json(self) -> dict[str, Any]:
        return {
            "name": self.conveyor,
            "what": self.what,
            "speed_max_mps": self.speed_max_mps,
            "window_m": list(self.window_m),
            "reachable_m": [list(r) for r in self.reachable_m],
            "latest_start_m": _rounded(self.latest_start_m),
            "speed_ok_mps": _rounded(self.speed_ok_mps),
            "tracked_s": round(self.tracked_s, 4),
            "parts_per_minute": round(self.parts_per_minute, 2),
            "min_pitch_m": round(self.min_pitch_m, 4),
            "cases_proved": sum(c.ok for c in self.cases),
            "cases_checked": len(self.cases),
            "error": self.error,
        }


def _rounded(x: float | None) -> float | None:
    return None if x is None else round(x, 4)


def prove_tracking(world: CellWorld, plan: TaskPlan) -> list[TrackingProof]:
    """The proof of every tracked stretch of an approved plan (none when it was refused:
    its steps are not planned)."""
    if not plan.ok:
        return []
    proofs = []
    for name, rows in tracked_stretches(plan):
        conveyor = world.loaded.cell.conveyors[name]
        piece = still_piece(world, plan, rows, SAMPLE_S)
        proofs.append(prove_stretch(world, name, conveyor, piece, plan.cycle_time_s))
    return proofs


# ------------------------------------------------------------------ the proof


def prove_stretch(
    world: CellWorld, name: str, conveyor: Conveyor, piece: TrackedPiece, cycle_s: float
) -> TrackingProof:
    lo, hi = (float(w) for w in conveyor.window)
    v_max = float(conveyor.speed_max)
    proof = TrackingProof(name, v_max, (lo, hi), piece.duration_s, cycle_s, what=piece.what)
    proof.reachable_m = reachable_spans(world, conveyor, piece)
    span = sum(b - a for a, b in proof.reachable_m)
    if not proof.reachable_m:
        proof.error = (
            f"conveyor {name!r}: the arm reaches none of the window [{lo:+.3f}, {hi:+.3f}] m "
            f"(the {piece.what}'s {'grip' if piece.what == 'pick' else 'set-down'} pose moved "
            "along the belt has no IK solution anywhere in it)"
        )
        return proof
    for fraction in SPEED_FRACTIONS:
        v = v_max * fraction
        cases = prove_speed(world, conveyor, piece, v)
        proof.cases.extend(cases)
        if fraction == 1.0:
            proof.latest_start_m = _latest_ok(cases)
    if proof.latest_start_m is None:
        still = [c for c in proof.cases if c.speed_mps == 0.0]
        # a belt that stands still fails too: no slower speed helps
        proof.speed_ok_mps = (
            _slower_speed(world, conveyor, piece) if _latest_ok(still) is not None else None
        )
        why = next((c.reason for c in proof.cases if c.speed_mps == v_max and not c.ok), "")
        can = (
            f"it can at {proof.speed_ok_mps:.3f} m/s"
            if proof.speed_ok_mps is not None
            else "it cannot at any speed, the belt standing still included"
            if _latest_ok(still) is None
            else "it cannot at any speed down to 5% of it"
        )
        proof.error_lines = [
            f"conveyor {name!r}: the {piece.what} cannot be made at {v_max:g} m/s anywhere in the "
            f"window [{lo:+.3f}, {hi:+.3f}] m ({why})",
            can,
        ]
        if span < hi - lo - 1e-9:
            proof.error_lines.append(
                f"the arm reaches {span:.3f} m of the window's {hi - lo:.3f} m"
            )
        return proof
    slower = [c for c in proof.cases if not c.ok]
    if slower:
        c = slower[0]
        proof.error = (
            f"conveyor {name!r}: at {c.speed_mps:g} m/s with the part at {c.start_m:+.3f} m "
            f"the {piece.what} fails: {c.reason}"
        )
    return proof


def reachable_spans(
    world: CellWorld, conveyor: Conveyor, piece: TrackedPiece
) -> list[tuple[float, float]]:
    """The stretches of the window (m from the frame) where the grip pose, moved along the
    belt, has an IK solution inside the joint limits."""
    lo, hi = (float(w) for w in conveyor.window)
    kin = world.kinematics
    T_grip = piece.T_world_tcp[piece.grip_index]
    q_grip = piece.q_rad[piece.grip_index]
    points = np.linspace(lo, hi, REACH_SAMPLES)
    ok = [bool(kin.ik_all(T_world_shift(conveyor.path, float(d)) @ T_grip, q_grip)) for d in points]
    spans: list[tuple[float, float]] = []
    start: float | None = None
    for d, good in zip(points, ok, strict=True):
        if good and start is None:
            start = float(d)
        if good:
            last = float(d)
        if not good and start is not None:
            spans.append((start, last))
            start = None
    if start is not None:
        spans.append((start, last))
    return spans


def latest_fitting_start_m(conveyor: Conveyor, tracked_s: float, speed_mps: float) -> float | None:
    """The latest start (m from the frame) whose ramp and tracked steps end before the
    part leaves the window, at ``speed_mps``; None when even the earliest does not."""
    lo, hi = (float(w) for w in conveyor.window)
    bounds = ramp_bounds(conveyor.path)
    first = nominal_start_m(speed_mps, lo, bounds)
    best = None
    for d0 in np.linspace(first, hi, START_CANDIDATES):
        end = d0 + speed_mps * (ramp_in(float(d0), speed_mps, bounds).duration_s + tracked_s)
        if end <= hi + 1e-9:
            best = float(d0)
    return best


def prove_speed(
    world: CellWorld, conveyor: Conveyor, piece: TrackedPiece, speed_mps: float
) -> list[CaseResult]:
    """The cases of one belt speed: starts from the earliest to the latest the window
    allows. A speed at which no start fits the window is one failed case."""
    lo = float(conveyor.window[0])
    bounds = ramp_bounds(conveyor.path)
    first = nominal_start_m(speed_mps, lo, bounds)
    last = latest_fitting_start_m(conveyor, piece.duration_s, speed_mps)
    if last is None:
        ramp_s = ramp_in(first, speed_mps, bounds).duration_s
        end = first + speed_mps * (ramp_s + piece.duration_s)
        return [
            CaseResult(
                speed_mps,
                first,
                False,
                f"the part leaves the window before the tracked steps end (it would be at "
                f"{end:+.3f} m, the window ends at {float(conveyor.window[1]):+.3f} m)",
            )
        ]
    starts = np.linspace(first, last, START_SAMPLES) if last > first else np.array([first])
    return [prove_case(world, conveyor, piece, speed_mps, float(d0)) for d0 in starts]


def _latest_ok(cases: list[CaseResult]) -> float | None:
    """The latest start of a run of proved starts from the earliest on."""
    latest = None
    for case in sorted(cases, key=lambda c: c.start_m):
        if not case.ok:
            break
        latest = case.start_m
    return latest


def _slower_speed(world: CellWorld, conveyor: Conveyor, piece: TrackedPiece) -> float | None:
    v_max = float(conveyor.speed_max)
    for fraction in SLOWER_FRACTIONS:
        v = v_max * fraction
        if _latest_ok(prove_speed(world, conveyor, piece, v)) is not None:
            return v
    return None


def prove_case(
    world: CellWorld, conveyor: Conveyor, piece: TrackedPiece, speed_mps: float, start_m: float
) -> CaseResult:
    """Reach, joint and TCP limits, and collisions of one belt speed and start."""
    _, failed = tracked_joint_path(world, conveyor, piece, speed_mps, start_m)
    if failed is not None:
        return CaseResult(speed_mps, start_m, False, failed)
    return CaseResult(speed_mps, start_m, True)


def tracked_joint_path(
    world: CellWorld, conveyor: Conveyor, piece: TrackedPiece, speed_mps: float, start_m: float
) -> tuple[np.ndarray, str | None]:
    """The commanded joint path of one belt speed and start, a sample every
    ``piece.sample_s`` (ramp in, the tracked steps, ramp out), and why it fails reach,
    limits or collisions (None: it passes). ``check`` proves cases with it; the run time
    approves the one case the belt's measured speed and the latched part make."""
    sigma, held, _, _ = commanded_offsets(piece, conveyor, speed_mps, start_m)
    kin, limits = world.kinematics, world.limits
    q = np.empty((len(sigma), 6))
    q_prev = piece.q_rad[0]
    for k, (s, h) in enumerate(zip(sigma, held, strict=True)):
        T = T_world_shift(conveyor.path, float(s)) @ piece.T_world_tcp[h]
        qk = kin.ik_track(T, q_prev)
        if qk is None or float(np.abs(qk - q_prev).max()) > 0.5:
            return q[:k], (
                f"no joined IK solution {k * piece.sample_s:.2f} s into the pick, the arm "
                f"{float(s):+.3f} m along the belt from the frame"
            )
        q[k] = q_prev = qk
    failed = _limit_failure(q, limits, kin, piece.sample_s)
    if failed is None:
        failed = _collision_failure(q, held, piece)
    return q, failed


def _limit_failure(q: np.ndarray, limits: Any, kin: Any, dt: float) -> str | None:
    if len(q) < 3:
        return None
    dq = np.diff(q, axis=0) / dt
    ddq = np.diff(dq, axis=0) / dt
    for what, values, bound, unit in (
        ("speed", dq, limits.joint_speed_rad_s, "deg/s"),
        ("acceleration", ddq, limits.joint_accel_rad_s2, "deg/s^2"),
    ):
        excess = np.abs(values) / np.asarray(bound)
        k, j = np.unravel_index(int(np.argmax(excess)), excess.shape)
        if excess[k, j] > 1.0 + LIMIT_TOLERANCE:
            return (
                f"joint {j + 1} {what} {math.degrees(abs(values[k, j])):.0f} {unit} over its "
                f"limit x margin {math.degrees(bound[j]):.0f} {unit} {k * dt:.2f} s in"
            )
    p = kin.p_world_tcp_many(q)
    v_tcp = np.linalg.norm(np.diff(p, axis=0), axis=1) / dt
    i = int(np.argmax(v_tcp))
    if v_tcp[i] > limits.tcp_speed_mps * (1.0 + LIMIT_TOLERANCE):
        return (
            f"TCP speed {v_tcp[i]:.2f} m/s over its cap x margin {limits.tcp_speed_mps:.2f} m/s "
            f"{i * dt:.2f} s in"
        )
    return None


def _collision_failure(q: np.ndarray, held: np.ndarray, piece: TrackedPiece) -> str | None:
    for model, (a, b) in zip(piece.models, piece.runs, strict=True):
        rows = np.nonzero((held >= a) & (held < b))[0]
        if not len(rows):
            continue
        lo, hi = int(rows[0]), int(rows[-1])
        # the ramps hold the first and last pose: they belong to the first and last runs
        if a == 0:
            lo = 0
        if b == len(piece.q_rad):
            hi = len(q) - 1
        check = model.check_path(q[lo : hi + 1])
        if not check.ok:
            where = f" ({check.clearance})" if check.clearance is not None else ""
            s = (lo + (check.s_blocked or 0.0)) * piece.sample_s
            return f"a collision {s:.2f} s into the pick{where}"
    return None
