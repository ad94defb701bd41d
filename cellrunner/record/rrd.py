"""A :class:`~cellrunner.record.sink.Sink` writing Rerun's ``.rrd`` (``rerun-sdk``, the
``cellrunner[record]`` extra): one timeline ``time`` (s of the backend's clock), the world
frame Z up, meshes static, poses as transforms of their entities (poses and plots sent
in column batches, ``BATCH_S``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from cellrunner.record.sink import Rgba

#: the timeline every entity is logged on
TIMELINE = "time"

#: poses and plot samples are sent in column batches this often (s of backend time)
BATCH_S = 0.5


def _colour(rgba: Rgba) -> list[int]:
    return [round(255 * c) for c in rgba]


class RerunSink:
    """Writes one ``.rrd`` file (see the module docstring)."""

    def __init__(self, path: Path, name: str) -> None:
        import rerun as rr

        self._rr: Any = rr
        self._rec: Any = rr.RecordingStream("cellrunner", recording_id=None)
        self._rec.save(str(path), default_blueprint=_layout())
        self._rec.send_recording_name(name)
        self._rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        self._poses: dict[str, list[tuple[float, np.ndarray]]] = {}
        self._scalars: dict[str, list[tuple[float, float]]] = {}
        self._flushed_s = -float("inf")

    def _at(self, time_s: float) -> None:
        self._rec.set_time(TIMELINE, duration=time_s)

    def mesh(self, path: str, vertices_m: np.ndarray, faces: np.ndarray, rgba: Rgba) -> None:
        rr = self._rr
        mesh = rr.Mesh3D(
            vertex_positions=np.asarray(vertices_m, np.float32),
            triangle_indices=np.asarray(faces, np.uint32),
            albedo_factor=_colour(rgba),
        )
        self._rec.log(path, mesh, static=True)

    def pose(self, time_s: float, path: str, T_parent_child: np.ndarray) -> None:
        self._poses.setdefault(path, []).append((time_s, T_parent_child))
        self._due(time_s)

    def _due(self, time_s: float) -> None:
        if time_s - self._flushed_s >= BATCH_S:
            self._flush()
            self._flushed_s = time_s

    def _flush(self) -> None:
        """The poses and plot samples held, one column batch per entity (a call per
        sample and entity would cost the process's GIL ~30 times as many Python calls)."""
        rr, rec = self._rr, self._rec
        for path, rows in self._poses.items():
            T = np.array([m for _, m in rows])
            rec.send_columns(
                path,
                indexes=[rr.TimeColumn(TIMELINE, duration=[t for t, _ in rows])],
                columns=rr.Transform3D.columns(translation=T[:, :3, 3], mat3x3=T[:, :3, :3]),
            )
        for path, samples in self._scalars.items():
            rec.send_columns(
                path,
                indexes=[rr.TimeColumn(TIMELINE, duration=[t for t, _ in samples])],
                columns=rr.Scalars.columns(scalars=[v for _, v in samples]),
            )
        self._poses, self._scalars = {}, {}

    def line(self, time_s: float, path: str, points_m: np.ndarray, rgba: Rgba) -> None:
        self._at(time_s)
        strip = self._rr.LineStrips3D([np.asarray(points_m, np.float32)], colors=[_colour(rgba)])
        self._rec.log(path, strip)

    def points(self, time_s: float, path: str, points_m: np.ndarray, rgba: Rgba) -> None:
        self._at(time_s)
        cloud = self._rr.Points3D(np.asarray(points_m, np.float32), colors=[_colour(rgba)])
        self._rec.log(path, cloud)

    def scalar(self, time_s: float, path: str, value: float) -> None:
        self._scalars.setdefault(path, []).append((time_s, value))
        self._due(time_s)

    def text(self, time_s: float, path: str, text: str, level: str) -> None:
        self._at(time_s)
        self._rec.log(path, self._rr.TextLog(text, level=level))

    def depth(self, time_s: float, path: str, depth_m: np.ndarray) -> None:
        self._at(time_s)
        depth = np.nan_to_num(np.asarray(depth_m, np.float32), posinf=0.0)
        self._rec.log(path, self._rr.DepthImage(depth, meter=1.0))

    def image(self, time_s: float, path: str, rgb: np.ndarray) -> None:
        self._at(time_s)
        self._rec.log(path, self._rr.Image(np.asarray(rgb, np.uint8)))

    def close(self) -> None:
        self._flush()
        self._rec.flush()
        self._rec.disconnect()


def _layout() -> Any:
    """The viewer's layout a recording opens with: the cell in 3D beside the plots and
    the step log."""
    import rerun.blueprint as rrb

    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="world", name="cell"),
            rrb.Vertical(
                rrb.TimeSeriesView(origin="plots/joints", name="joints (rad)"),
                rrb.TimeSeriesView(origin="plots/wrist", name="wrist force (N)"),
                rrb.TimeSeriesView(origin="plots/io", name="IO"),
                rrb.TextLogView(origin="steps", name="steps"),
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )
