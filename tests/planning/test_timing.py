"""Time parameterization: near the continuous optimum, limits at every sample, local
slow-down, and toppra without matplotlib."""

from __future__ import annotations

import ast
import subprocess
import sys

import numpy as np

from cellrunner.model.robots import ROBOTS
from cellrunner.planning import timing
from cellrunner.planning.kinematics import ArmKinematics
from cellrunner.planning.timing import MotionLimits, optimal_duration_s, sample_measures, time_path
from tests.conftest import ROOT

SPEC = ROBOTS["ur5e"]
KIN = ArmKinematics(SPEC, np.eye(4), np.eye(4))
LIMITS = MotionLimits.from_cell(
    SPEC, joint_speed_deg_s=120, joint_accel_deg_s2=300, tcp_speed_mps=1.0
)


def _cornered_path() -> np.ndarray:
    """Two long joint moves joined by a short, tight arc (what corner rounding makes)."""
    a, w, b = np.radians(
        [[0, -90, 90, -90, -90, 0], [60, -70, 60, -90, -90, 40], [100, -100, 110, -70, -90, 0]]
    )
    t = np.linspace(0, 1, 32)[:, None]
    p1, p2 = w + 0.05 * (a - w), w + 0.05 * (b - w)
    arc = (1 - t) ** 2 * p1 + 2 * (1 - t) * t * w + t**2 * p2
    return np.vstack([a, arc, b])


def _worst_ratio(
    q: np.ndarray, limits: MotionLimits, kin: ArmKinematics = KIN, rate_hz: float = SPEC.rate_hz
) -> float:
    v, a, tcp = sample_measures(kin, q, rate_hz)
    return max(
        float((np.abs(v) / limits.joint_speed_rad_s).max()),
        float((np.abs(a) / limits.joint_accel_rad_s2).max()),
        float(tcp.max() / limits.tcp_speed_mps),
    )


def test_timed_path_keeps_every_limit_and_is_within_two_percent_of_the_optimum():
    path = _cornered_path()
    timed = time_path(KIN, path, LIMITS, SPEC.rate_hz)
    assert _worst_ratio(timed.q_rad, LIMITS) <= 1 + 1e-9
    assert np.allclose(timed.q_rad[0], path[0]) and np.allclose(timed.q_rad[-1], path[-1])
    bound = optimal_duration_s(KIN, path, LIMITS)
    assert bound <= timed.t_s[-1] <= 1.02 * bound


def _straight_line_path(kin: ArmKinematics, length_m: float, points: int) -> np.ndarray:
    """Joint samples of a straight TCP line down world -Z (IK, nearest branch)."""
    from cellrunner.model.geometry import pose_matrix

    q = [np.radians([0, -90, 90, -90, -90, 0])]
    for z in np.linspace(0.45, 0.45 - length_m, points):
        q.append(kin.ik_nearest(pose_matrix((0.45, -0.15, z), (180, 0, 0)), q[-1]))
    return np.array(q[1:])


def test_a_slow_straight_move_under_the_tcp_cap_is_not_stretched_at_its_ends():
    """Peg insertion at 10 mm/s: 13 IK samples, a 40-point grid. A first interval of
    100 ms at constant path acceleration cost 5% of the move before the grid was
    refined where the speed changes."""
    path = _straight_line_path(KIN, 0.05, 13)
    slow = LIMITS.scaled(tcp_speed_mps=0.01)
    timed = time_path(KIN, path, slow, SPEC.rate_hz)
    assert _worst_ratio(timed.q_rad, slow) <= 1 + 1e-9
    bound = optimal_duration_s(KIN, timed.q_rad, slow)
    assert bound <= timed.t_s[-1] <= 1.005 * bound


def test_a_cb3_rate_path_is_within_two_percent_of_the_optimum_on_what_is_streamed():
    """At 125 Hz, against the bound on the streamed samples themselves (bench_cycle's)."""
    cb3 = ROBOTS["ur5"]
    kin = ArmKinematics(cb3, np.eye(4), np.eye(4))
    limits = MotionLimits.from_cell(cb3, joint_speed_deg_s=120, joint_accel_deg_s2=300)
    timed = time_path(kin, _cornered_path(), limits, cb3.rate_hz)
    assert _worst_ratio(timed.q_rad, limits, kin, cb3.rate_hz) <= 1 + 1e-9
    bound = optimal_duration_s(kin, timed.q_rad, limits)
    assert bound <= timed.t_s[-1] <= 1.02 * bound


def test_refining_splits_only_where_the_speed_changes():
    problem = timing._Problem(KIN, _cornered_path(), LIMITS)
    sd = problem.solve(problem.tcp_cap)
    before = problem.grid.copy()
    cruising = sd >= (1 - timing.REFINE_CRUISE_TOLERANCE) * problem.speed_bound(problem.tcp_cap)
    assert problem.refine(sd)
    assert set(before) <= set(problem.grid)
    for a, b, c1, c2 in zip(before[:-1], before[1:], cruising[:-1], cruising[1:], strict=True):
        inside = int(((problem.grid > a) & (problem.grid < b)).sum())
        if c1 and c2:
            assert inside == 0
    sd2 = problem.solve(problem.tcp_cap)
    dt = 2 * np.diff(problem.grid) / np.maximum(sd2[:-1] + sd2[1:], 1e-12)
    assert timing._s_of_time(sd2, problem.grid)[1] <= timing._s_of_time(sd, before)[1]
    assert np.median(dt) <= 2 * timing.REFINE_INTERVAL_S


def test_a_wide_corner_arc_is_timed_as_a_curve_not_as_a_polygon():
    """An arc over half of each edge (joint_path.round_corners), 32 points 0.024-0.034 rad
    apart: a knot added inside each chord made the spline straight between the arc's
    points and kinked at them, 7% slower (1.622 s against 1.512 s)."""
    a, w, b = np.radians(
        [[0, -90, 90, -90, -90, 0], [60, -70, 60, -90, -90, 40], [100, -100, 110, -70, -90, 0]]
    )
    t = np.linspace(0, 1, 32)[:, None]
    p1, p2 = w + 0.5 * (a - w), w + 0.5 * (b - w)
    path = np.vstack([a, (1 - t) ** 2 * p1 + 2 * (1 - t) * t * w + t**2 * p2, b])
    timed = time_path(KIN, path, LIMITS, SPEC.rate_hz)
    assert _worst_ratio(timed.q_rad, LIMITS) <= 1 + 1e-9
    assert timed.t_s[-1] <= 1.01 * optimal_duration_s(KIN, path, LIMITS)


def test_densify_splits_long_edges_only():
    wp = np.array([np.zeros(6), np.full(6, 0.05), np.full(6, 0.05) + [0.31, 0, 0, 0, 0, 0]])
    dense, s_dense, s_wp = timing._densify(wp)
    assert len(dense) == 1 + 1 + 11  # the short edge whole, the long one in 0.03 rad pieces
    assert np.abs(np.diff(dense[1:], axis=0)).max() <= timing.DENSIFY_STEP_RAD
    assert np.allclose(dense[[0, 1, -1]], wp) and np.isclose(s_dense[-1], s_wp[-1])


def test_a_violation_slows_down_only_the_grid_points_around_it():
    grid = np.linspace(0.0, 1.0, 101)
    sd = np.full(101, 2.0)
    cap = np.full(101, np.inf)
    s_samples = np.linspace(0.0, 1.0, 501)
    excess = np.ones(501)
    excess[250] = 1.2  # one sample over its limit, at s = 0.5
    capped = timing._capped_locally(grid, sd, cap, s_samples, excess)
    slowed = np.isfinite(capped)
    assert slowed[50] and capped[50] == 2.0 * timing.RESAMPLE_HEADROOM / 1.2
    assert slowed.sum() <= 8  # a few grid points either side, not the whole motion
    assert not slowed[:40].any() and not slowed[60:].any()


def test_toppra_loads_without_matplotlib():
    code = (
        "import sys; from cellrunner.planning.timing import _import_toppra; t = _import_toppra(); "
        "import toppra.algorithm; assert 'matplotlib' not in sys.modules, 'matplotlib'; "
        "assert 'matplotlib.pyplot' not in sys.modules; print('clean')"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "clean"


def _modules_after(tmp_path, *commands: list[str]) -> list[str]:
    """The heavy modules loaded after running ``commands`` through the CLI in one process."""
    code = (
        "import sys, contextlib, io\n"
        "from cellrunner.cli.main import main\n"
        "with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):\n"
        + "".join(f"    assert main({c!r}) == 0\n" for c in commands)
        + "print(sorted(m for m in sys.modules if m.startswith(('matplotlib', 'scipy', 'toppra'))))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return ast.literal_eval(done.stdout.strip())


def test_validate_and_a_warm_check_import_no_scipy_toppra_or_matplotlib(tmp_path):
    cell, task = str(ROOT / "cells/demo_ur5e.yaml"), str(ROOT / "tasks/pick_place.yaml")
    _modules_after(tmp_path, ["check", cell, task, "--json"])  # fills the plan cache
    assert _modules_after(tmp_path, ["validate", cell], ["check", cell, task, "--json"]) == []


def test_a_cold_check_imports_no_matplotlib(tmp_path):
    cell, task = str(ROOT / "cells/demo_ur5e.yaml"), str(ROOT / "tasks/pick_place.yaml")
    loaded = _modules_after(tmp_path, ["check", cell, task, "--json", "--no-cache"])
    assert "toppra" in loaded
    assert [m for m in loaded if m.startswith("matplotlib")] == []
