"""The picture of docs/recordings.md, from a real run: what a ``.rrd`` recording holds at
one moment (the meshes at their recorded poses, the planned and measured TCP paths), read
back with Rerun's own reader and drawn headless, beside the twin's render of the same
moment from ``dry-run --report``.

    PYTHONPATH=. MUJOCO_GL=osmesa python -m cellrunner.cli.main dry-run \\
        cells/demo_ur5e.yaml tasks/pick_place.yaml --report run --record run.rrd
    PYTHONPATH=. python scripts/recording_picture.py run.rrd run/step04_grip.png \\
        docs/images/recording.png
"""

from __future__ import annotations

import sys
from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from mpl_toolkits.mplot3d.art3d import Poly3DCollection
from rerun.chunk import RrdReader


def read(path: Path) -> tuple[dict, dict, dict, list]:
    """Meshes (vertices, faces, colour) and poses (time, 4x4) by entity, line strips by
    entity (time, points), step log lines (time, text)."""
    meshes, poses, lines, steps = {}, defaultdict(list), defaultdict(list), []
    for chunk in RrdReader(path).store().stream():
        b, p = chunk.to_record_batch(), chunk.entity_path
        names = b.schema.names
        if "Mesh3D:vertex_positions" in names:
            v = np.array(b.column("Mesh3D:vertex_positions").to_pylist()[0])
            f = np.array(b.column("Mesh3D:triangle_indices").to_pylist()[0])
            c = b.column("Mesh3D:albedo_factor").to_pylist()[0][0]
            meshes[p] = (v, f, [((c >> s) & 255) / 255 for s in (24, 16, 8, 0)])
        if "Transform3D:translation" in names:
            for t, tr, m in zip(
                b.column("time").to_pylist(),
                b.column("Transform3D:translation").to_pylist(),
                b.column("Transform3D:mat3x3").to_pylist(),
                strict=True,
            ):
                T = np.eye(4)
                T[:3, :3] = np.array(m[0]).reshape(3, 3).T  # Rerun stores columns
                T[:3, 3] = tr[0]
                poses[p].append((t, T))
        if "LineStrips3D:strips" in names:
            for t, s in zip(
                b.column("time").to_pylist(),
                b.column("LineStrips3D:strips").to_pylist(),
                strict=True,
            ):
                lines[p].append((t, np.array(s[0])))
        if "TextLog:text" in names:
            steps += zip(
                b.column("time").to_pylist(),
                (r[0] for r in b.column("TextLog:text").to_pylist()),
                strict=True,
            )
    return meshes, poses, lines, steps


def at(rows: list, t: object) -> object:
    """The last value at or before ``t``."""
    rows = sorted(rows, key=lambda r: r[0])
    before = [v for time, v in rows if time <= t]
    return before[-1] if before else rows[0][1]


def main(rrd: Path, twin_png: Path, out: Path) -> None:
    meshes, poses, lines, steps = read(rrd)
    grip = min(t for t, text in steps if text.startswith("step 6 ") and "started" in text)  # held
    fig = plt.figure(figsize=(14, 6.2), dpi=110)
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    ax.computed_zorder = False  # drawn in order: the fixtures first, the arm and part on top
    for path, (v, f, colour) in sorted(meshes.items(), key=lambda m: "/static/" not in m[0]):
        body = path.rsplit("/", 1)[0]
        T = at(poses[body], grip) if body in poses else np.eye(4)
        w = v @ T[:3, :3].T + T[:3, 3]
        ax.add_collection3d(Poly3DCollection(w[f], facecolor=colour, edgecolor="none", alpha=0.9))
    planned = np.vstack([pts for _, pts in lines["/world/paths/planned"]])
    measured = max(lines["/world/paths/measured"], key=lambda r: r[0])[1]  # the whole path
    ax.plot(*planned.T, ".", color="#2f7bff", ms=2, label="planned TCP path (each motion)")
    ax.plot(*measured.T, "-", color="#ff8c1a", lw=1.5, label="measured TCP path")
    centre = (measured.min(axis=0) + measured.max(axis=0)) / 2
    half = (measured.max(axis=0) - measured.min(axis=0)).max() / 2 + 0.3
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=30, azim=-125)
    ax.set_xlabel("x (m)"), ax.set_ylabel("y (m)"), ax.set_zlabel("z (m)")
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title(f"the .rrd read back at {grip.total_seconds():.2f} s: step 6, the part held")
    ax2 = fig.add_subplot(1, 2, 2)
    ax2.imshow(plt.imread(twin_png))
    ax2.axis("off")
    ax2.set_title("the twin at the grip (dry-run --report)")
    fig.tight_layout()
    fig.savefig(out)


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]), Path(sys.argv[3]))
