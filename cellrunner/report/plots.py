"""Plots of a run: the TCP path over the fixtures (top and side), joints, wrist force and
IO against time, each with a lane of the steps on top (matplotlib, no display).

Positions are in the world frame (m), times from the run's first sample (s).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.model.step_kinds import STEP_KINDS

if TYPE_CHECKING:
    from cellrunner.model.geometry import Placed
    from cellrunner.report.recorder import Mark

#: a label's box in display pixels: (x0, y0, x1, y1)
Box2D = tuple[float, float, float, float]

#: points closer than this (m) share one label in the path plots
LABEL_MERGE_M = 0.015


def figure(width_in: float, height_in: float) -> Any:
    from matplotlib.figure import Figure  # no pyplot: no global state, no display

    return Figure(figsize=(width_in, height_in), dpi=100)


def save(fig: Any, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    return path


# -- the TCP path over the fixtures -------------------------------------------------------------


def shape_points_world(placed: Placed) -> np.ndarray:
    """Points on a placed shape's surface in the world (m): box corners, rings of a
    cylinder's ends, a sphere's bounding box, a mesh's vertices."""
    from cellrunner.model.geometry import Box, Cylinder, Sphere, Voxels

    shape = placed.shape
    if isinstance(shape, Box):
        hx, hy, hz = (s / 2 for s in shape.size_m)
        local = np.array([[x, y, z] for x in (-hx, hx) for y in (-hy, hy) for z in (-hz, hz)])
    elif isinstance(shape, Cylinder):
        a = np.linspace(0, 2 * np.pi, 32, endpoint=False)
        ring = np.column_stack([shape.radius_m * np.cos(a), shape.radius_m * np.sin(a)])
        local = np.vstack(
            [
                np.column_stack([ring, np.full(32, z)])
                for z in (-shape.length_m / 2, shape.length_m / 2)
            ]
        )
    elif isinstance(shape, Sphere):
        r = shape.radius_m
        a = np.linspace(0, 2 * np.pi, 32, endpoint=False)
        local = np.vstack(
            [
                np.column_stack([r * np.cos(a), r * np.sin(a), np.zeros(32)]),
                np.column_stack([r * np.cos(a), np.zeros(32), r * np.sin(a)]),
                np.column_stack([np.zeros(32), r * np.cos(a), r * np.sin(a)]),
            ]
        )
    elif isinstance(shape, Voxels):
        local = np.asarray(shape.centres_m, float)
    else:
        from cellrunner.planning.stl import read_stl

        vertices, _ = read_stl(shape.path)
        local = np.asarray(vertices, float).reshape(-1, 3) * getattr(shape, "scale", 1.0)
    T = np.asarray(placed.T_parent_shape, float)
    return np.asarray(local @ T[:3, :3].T + T[:3, 3])


def _outline(points_2d: np.ndarray) -> np.ndarray:
    """The convex outline of 2-D points (a degenerate set gives its bounding box)."""
    from scipy.spatial import ConvexHull, QhullError

    try:
        hull = ConvexHull(points_2d)
        return points_2d[hull.vertices]
    except (QhullError, ValueError):
        lo, hi = points_2d.min(axis=0), points_2d.max(axis=0)
        return np.array([lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]])


def merged_labels(points: list[tuple[str, np.ndarray]]) -> list[tuple[str, np.ndarray]]:
    """Labels of points that (nearly) coincide joined into one: '3 descend, 4 grip'."""
    out: list[tuple[list[str], np.ndarray]] = []
    for label, p in points:
        for labels, q in out:
            if np.linalg.norm(np.asarray(p) - q) < LABEL_MERGE_M:
                if label not in labels:
                    labels.append(label)
                break
        else:
            out.append(([label], np.asarray(p, float)))
    return [(", ".join(labels), p) for labels, p in out]


def plot_tcp_path(
    path: Path,
    tcp_m: np.ndarray,
    fixtures: list[Placed],
    base_m: np.ndarray,
    step_points: list[tuple[str, np.ndarray]],
    title: str,
    obstacles_m: np.ndarray | None = None,
) -> Path:
    """The TCP path seen from above (x-y) and from the side (x-z, and y-z), the fixtures
    drawn as their outlines, the robot base as a disc, each step's start labelled; in a
    watched cell the voxels the obstacle map held occupied (``obstacles_m``, world centres,
    N x 3) as small squares."""
    tcp = np.asarray(tcp_m, float)
    fig = figure(15, 5.6)
    axes = fig.subplots(1, 3)
    views = (("top (x-y)", 0, 1), ("side (x-z)", 0, 2), ("front (y-z)", 1, 2))
    labels = merged_labels(step_points)
    if obstacles_m is not None and not len(obstacles_m):
        obstacles_m = None
    work = np.vstack([tcp, base_m[None, :]])
    if obstacles_m is not None:
        work = np.vstack([work, obstacles_m])
    for ax, (name, i, j) in zip(axes, views, strict=True):
        _frame_axes(ax, work[:, [i, j]])
        (x0, x1), (_, y1) = ax.get_xlim(), ax.get_ylim()
        for placed in fixtures:
            _draw_fixture(ax, placed, (i, j), (x0, x1), y1)
        _draw_base(ax, base_m, (i, j))
        if obstacles_m is not None:
            _draw_obstacles(ax, obstacles_m, (i, j))
        _draw_tcp(ax, tcp, (i, j), (x0, x1))
        _frame_axes(ax, work[:, [i, j]])  # again: the fixtures' fills moved the limits
        _draw_step_labels(ax, labels, (i, j))
        ax.set_xlabel(f"{'xyz'[i]} [m]")
        ax.set_ylabel(f"{'xyz'[j]} [m]")
        ax.set_title(name, fontsize=10)
        ax.grid(alpha=0.25)
    axes[0].legend(fontsize=7, loc="lower left")
    fig.suptitle(title)
    fig.tight_layout()
    return save(fig, path)


def _draw_fixture(
    ax: Any, placed: Placed, view: tuple[int, int], x_lim_m: tuple[float, float], y_top_m: float
) -> None:
    """One fixture's outline in the view (world axes ``view``, m), its name under the middle
    of its top edge and inside the frame ``x_lim_m``, ``y_top_m``, so labels of nested
    outlines part."""
    i, j = view
    x0, x1 = x_lim_m
    outline = _outline(shape_points_world(placed)[:, [i, j]])
    ax.fill(
        outline[:, 0],
        outline[:, 1],
        color="#c9a66b",
        alpha=0.35,
        lw=1.0,
        ec="#8b6d3f",
        zorder=1,
    )
    top_y = float(outline[:, 1].max())
    top_x = float(np.mean(outline[outline[:, 1] > top_y - 1e-6, 0]))
    ax.text(
        min(max(top_x, x0 + 0.1 * (x1 - x0)), x1 - 0.1 * (x1 - x0)),
        min(top_y, y_top_m),
        placed.name,
        fontsize=8,
        color="#6b4f25",
        ha="center",
        va="top",
        zorder=2,
        clip_on=True,
    )


def _draw_base(ax: Any, base_m: np.ndarray, view: tuple[int, int]) -> None:
    """The robot base (world position, m) as a labelled disc."""
    i, j = view
    ax.scatter([base_m[i]], [base_m[j]], s=160, color="#4a78c2", alpha=0.5, zorder=2)
    ax.text(base_m[i], base_m[j], " robot", fontsize=8, color="#2b4f8c", va="bottom", zorder=2)


def _draw_obstacles(ax: Any, obstacles_m: np.ndarray, view: tuple[int, int]) -> None:
    """The occupied voxels (world centres, m, N x 3) as small squares."""
    i, j = view
    ax.scatter(
        obstacles_m[:, i],
        obstacles_m[:, j],
        s=6,
        marker="s",
        color="#7b2cbf",
        alpha=0.35,
        zorder=2,
        label="obstacle map (occupied)",
    )


def _draw_tcp(
    ax: Any, tcp_m: np.ndarray, view: tuple[int, int], x_lim_m: tuple[float, float]
) -> None:
    """The TCP path (world, m, N x 3) with its start and end marked; the x limits stay
    ``x_lim_m``, the y limits as they were before the path."""
    i, j = view
    ax.plot(tcp_m[:, i], tcp_m[:, j], lw=1.6, color="#d62728", zorder=3, label="TCP")
    ax.set_xlim(*x_lim_m)
    ax.set_ylim(*ax.get_ylim())
    ax.scatter(*tcp_m[0, [i, j]], color="green", s=28, zorder=4, label="start")
    ax.scatter(*tcp_m[-1, [i, j]], color="black", s=28, marker="x", zorder=4, label="end")


def _draw_step_labels(ax: Any, labels: list[tuple[str, np.ndarray]], view: tuple[int, int]) -> None:
    """Each step's start (world, m) as a dot and its label, placed where no other label is."""
    i, j = view
    placed_boxes: list[Box2D] = []
    for label, p in labels:
        ax.scatter([p[i]], [p[j]], s=12, color="#333333", zorder=4)
        xy = ax.transData.transform((p[i], p[j]))
        offset = free_offset(xy, label, placed_boxes, 7)
        ax.annotate(
            label,
            (p[i], p[j]),
            xytext=offset,
            textcoords="offset pixels",
            fontsize=7,
            color="#222222",
            zorder=5,
            arrowprops={"arrowstyle": "-", "color": "#999999", "lw": 0.5},
        )


#: label offsets tried (pixels, right/up), nearest first
_OFFSETS = [
    (8, 8),
    (8, -16),
    (-8, 8),
    (-8, -16),
    (8, 24),
    (8, -32),
    (-8, 24),
    (-8, -32),
    (8, 40),
    (8, -48),
]


def free_offset(
    xy_px: Sequence[float], label: str, placed: list[Box2D], font_pt: float
) -> tuple[float, float]:
    """An offset (display pixels, y up) for ``label`` anchored at display point ``xy_px``
    whose box overlaps none of the boxes in ``placed`` (which it then joins); the first
    candidate when all overlap. The box is estimated from the text length."""
    w, h = 0.6 * font_pt * len(label) * 100 / 72 + 4, font_pt * 100 / 72 + 4
    first: tuple[tuple[float, float], Box2D] | None = None
    for dx, dy in _OFFSETS:
        x0 = xy_px[0] + (dx - w if dx < 0 else dx)
        box = (x0, xy_px[1] + dy, x0 + w, xy_px[1] + dy + h)
        candidate = ((dx - w if dx < 0 else dx, float(dy)), box)
        first = first or candidate
        if all(box[2] < b[0] or box[0] > b[2] or box[3] < b[1] or box[1] > b[3] for b in placed):
            break
    else:
        assert first is not None  # there are offsets to try
        candidate = first
    placed.append(candidate[1])
    return candidate[0]


def _frame_axes(ax: Any, pts: np.ndarray, pad_m: float = 0.12) -> None:
    """Equal scale, framed on the work (the TCP path and the base) with a margin, so a
    large table or a far wall does not shrink the path to a dot."""
    lo, hi = pts.min(axis=0) - pad_m, pts.max(axis=0) + pad_m
    half = float((hi - lo).max()) / 2
    c = (lo + hi) / 2
    ax.set_xlim(c[0] - half, c[0] + half)
    ax.set_ylim(c[1] - half, c[1] + half)
    ax.set_aspect("equal", adjustable="box")


# -- against time ----------------------------------------------------------------------------------


def step_spans(
    marks: list[tuple[float, int, str, str]], t_end_s: float
) -> list[tuple[float, float, int, str]]:
    """(start s, end s, index, kind) of each step from its start marks."""
    spans = []
    for k, (t, index, kind, _name) in enumerate(marks):
        end = marks[k + 1][0] if k + 1 < len(marks) else t_end_s
        spans.append((t, end, index, kind))
    return spans


def draw_steps_lane(ax: Any, marks: list[Mark], t_end_s: float) -> None:
    """A lane of coloured bars, one per step (index inside, kind below when it fits),
    alternating between two rows so that short steps' labels never overlap."""
    for k, (t0, t1, index, kind) in enumerate(step_spans(marks, t_end_s)):
        row = k % 2
        ax.barh(row, t1 - t0, left=t0, height=0.8, color=_colour(kind), ec="white")
        text = f"{index} {kind}" if (t1 - t0) > 0.06 * t_end_s else str(index)
        ax.text((t0 + t1) / 2, row, text, ha="center", va="center", fontsize=7, clip_on=True)
    ax.set_ylim(-0.5, 1.5)
    ax.set_yticks([])
    ax.set_ylabel("steps", rotation=0, ha="right", va="center")
    ax.set_xlim(0, t_end_s)


def plot_joints(
    path: Path,
    t_s: np.ndarray,
    q_rad: np.ndarray,
    qd_rad_s: np.ndarray,
    q_cmd_rad: np.ndarray,
    marks: list[Mark],
    title: str,
) -> Path:
    """Joint positions (deg; commanded dashed) and speeds (deg/s) under the steps lane."""
    fig = figure(12, 8)
    lane, ax_q, ax_qd = fig.subplots(3, 1, sharex=True, gridspec_kw={"height_ratios": [0.6, 3, 2]})
    draw_steps_lane(lane, marks, float(t_s[-1]))
    for j in range(6):
        (line,) = ax_q.plot(t_s, np.degrees(q_rad[:, j]), lw=1.3, label=f"q{j + 1}")
        ax_q.plot(t_s, np.degrees(q_cmd_rad[:, j]), lw=0.8, ls="--", color=line.get_color())
        ax_qd.plot(t_s, np.degrees(qd_rad_s[:, j]), lw=1.1, color=line.get_color())
    ax_q.set_ylabel("position [deg]")
    ax_qd.set_ylabel("speed [deg/s]")
    ax_qd.set_xlabel("time [s]")
    ax_q.legend(
        fontsize=8,
        loc="upper left",
        bbox_to_anchor=(1.005, 1.0),
        title="measured\n(commanded --)",
        title_fontsize=7,
    )
    for ax in (ax_q, ax_qd):
        ax.grid(alpha=0.3)
        for t0, *_ in marks:
            ax.axvline(t0, color="0.75", lw=0.6)
    lane.set_title(title)
    fig.tight_layout()
    return save(fig, path)


def plot_timelines(
    path: Path,
    t_s: np.ndarray,
    force_N: np.ndarray,
    io: dict[str, np.ndarray],
    marks: list[Mark],
    title: str,
    force_window_N: tuple[float | None, float | None] | None = None,
) -> Path:
    """Wrist force magnitude (N) and one lane per IO signal (outputs and inputs) under
    the steps lane; ``force_window_N``: the grip's (min, max) shaded."""
    names = list(io)
    ratios = [0.6, 2.2] + [0.5] * len(names)
    fig = figure(12, 3.2 + 0.55 * len(names) + 1.5)
    axes = fig.subplots(len(ratios), 1, sharex=True, gridspec_kw={"height_ratios": ratios})
    lane, ax_f, lanes = axes[0], axes[1], axes[2:]
    t_end = float(t_s[-1]) if len(t_s) else 1.0
    draw_steps_lane(lane, marks, t_end)
    ax_f.plot(t_s, force_N, lw=1.2, color="#9467bd")
    if force_window_N is not None:
        for bound, what in zip(force_window_N, ("min", "max"), strict=True):
            if bound is not None:
                ax_f.axhline(bound, color="#9467bd", ls=":", lw=1.0)
                ax_f.text(
                    t_end,
                    bound,
                    f" grip {what} {bound:g} N",
                    fontsize=7,
                    va="center",
                    color="#6b3fa0",
                )
    ax_f.set_ylabel("wrist force [N]")
    ax_f.grid(alpha=0.3)
    for ax, name in zip(lanes, names, strict=True):
        values = np.asarray(io[name], float)
        ax.fill_between(t_s, 0, values, step="post", color="#2ca02c", alpha=0.6)
        ax.step(t_s, values, where="post", color="#1a661a", lw=0.8)
        ax.set_ylim(-0.1, max(1.1, float(values.max(initial=0)) * 1.1))
        ax.set_yticks([])
        ax.set_ylabel(name, rotation=0, ha="right", va="center", fontsize=8)
    for ax in axes[1:]:
        for t0, *_ in marks:
            ax.axvline(t0, color="0.8", lw=0.6)
    axes[-1].set_xlabel("time [s]")
    lane.set_title(title)
    fig.tight_layout()
    return save(fig, path)


def plot_slot_cycles(
    path: Path, cycles: list[tuple[int, float | None]], param: str, title: str
) -> Path:
    """Planned cycle time per slot (s), the worst slot in red, infeasible slots marked."""
    fig = figure(9, 3.6)
    ax = fig.subplots()
    feasible = [(s, c) for s, c in cycles if c is not None]
    worst = max(feasible, key=lambda sc: sc[1])[0] if feasible else None
    for slot, cycle in cycles:
        if cycle is None:  # at the foot of the axis, whatever its range
            ax.text(
                slot,
                0.03,
                "infeasible",
                ha="center",
                va="bottom",
                color="red",
                fontsize=8,
                rotation=90,
                transform=ax.get_xaxis_transform(),
            )
            continue
        ax.bar(slot, cycle, color="#d62728" if slot == worst else "#7f9fcf")
        ax.text(slot, cycle, f"{cycle:.2f}", ha="center", va="bottom", fontsize=7)
    if feasible:  # the differences between slots matter here, not the bars' full height
        low, high = min(c for _, c in feasible), max(c for _, c in feasible)
        ax.set_ylim(
            max(0.0, low - max(0.5 * (high - low), 0.05 * low)),
            high + max(0.25 * (high - low), 0.01 * high),
        )
    ax.set_xlabel(param)
    ax.set_ylabel("planned cycle [s] (axis not from 0)" if feasible else "planned cycle [s]")
    ax.set_xticks([s for s, _ in cycles])
    ax.set_title(title)
    ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    return save(fig, path)


def plot_wrist_force(
    path: Path, trace: list[tuple[float, int, float]], limits_N: dict[int, float], title: str = ""
) -> Path:
    """The wrist force rise (N, above the step's standing baseline) against time (s) during
    the force steps (move_until_contact, insert), one line per step, its stop limit dashed."""
    fig = figure(8, 4)
    ax = fig.add_subplot()
    data = np.asarray(trace, float)
    t0 = data[0, 0]
    for index in sorted({int(i) for i in data[:, 1]}):
        rows = data[data[:, 1] == index]
        (line,) = ax.plot(rows[:, 0] - t0, rows[:, 2], lw=1.5, label=f"step {index}")
        if index in limits_N:
            ax.axhline(limits_N[index], ls="--", lw=1.0, color=line.get_color())
    ax.set_xlabel("t [s]")
    ax.set_ylabel("wrist force rise [N]")
    ax.legend(fontsize=8)
    if title:
        ax.set_title(title)
    fig.tight_layout()
    return save(fig, Path(path))


def _colour(kind: str) -> str:
    """The colour of a step kind's bar (its module's), grey for what is not a kind."""
    known = STEP_KINDS.get(kind)
    return known.colour if known is not None else "#dddddd"
