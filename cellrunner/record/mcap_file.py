"""A :class:`~cellrunner.record.sink.Sink` writing MCAP that Foxglove opens as a robot's
log: Foxglove's well-known schemas in protobuf (``foxglove-schemas-protobuf``, published
by Foxglove with the schemas, written with ``mcap`` and ``mcap-protobuf-support``):

    /tf                  foxglove.FrameTransforms   each body's frame in ``world``, the TCP
                                                    (one message per sample)
    /scene               foxglove.SceneUpdate       the meshes, one entity per geom,
                                                    locked to its body's frame
    /paths               foxglove.SceneUpdate       the planned and measured TCP paths
    /obstacles           foxglove.PointCloud        the obstacle map's occupied cells
    /log                 foxglove.Log               the step timeline with results
    /cameras/NAME/...    foxglove.RawImage          depth (32FC1) and colour (rgb8) images
    /plots               JSON (jsonschema)          joints, wrist force, IO, step: one
                                                    object per sample, plotted by field

Log times are the backend's clock (ns); a static mesh is written with the first timed
message so the file starts where the run does."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from cellrunner.record.sink import Rgba

_PLOTS_SCHEMA = {
    "title": "cellrunner.Plots",
    "type": "object",
    "description": "One sample of a job's plots: joints (rad), wrist force (N), IO, step",
    "properties": {},
    "additionalProperties": True,
}


#: meshes already built, by (path, the vertex array's id, its length, colour): serve's
#: recordings repeat the same scene in every file, built once (protobuf objects are slow
#: to build in Python; the cached array is kept, so its id is not reused)
_MESHES: dict[tuple[str, int, int, Rgba], tuple[np.ndarray, Any]] = {}


#: MCAP chunk size (bytes)
CHUNK_BYTES = 256 * 1024

#: vertices built per protobuf call before the worker lets other threads run
_POINTS_PER_SLICE = 2000


def quaternion_xyzw(R: np.ndarray) -> tuple[float, float, float, float]:
    """The unit quaternion (x, y, z, w) of rotation matrix ``R`` (Shepperd's method)."""
    m = R
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * np.sqrt(trace + 1.0)
        q = (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = s / 4, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = (m[0, 1] + m[1, 0]) / s, s / 4, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, s / 4, (m[1, 0] - m[0, 1]) / s
    x, y, z, w = (float(v) for v in q)
    return x, y, z, w


def frame_of(path: str) -> str:
    """The Foxglove frame id of an entity path: ``world/<body>[/geom]`` -> ``<body>``."""
    parts = path.split("/")
    if len(parts) < 2 or parts[1] == "static":
        return "world"
    return parts[1]


def _ns(time_s: float) -> int:
    return max(0, round(time_s * 1e9))


class McapSink:
    """Writes one ``.mcap`` file (see the module docstring)."""

    def __init__(self, path: Path, name: str) -> None:
        from foxglove_schemas_protobuf import Color_pb2, Log_pb2, SceneUpdate_pb2
        from mcap.writer import CompressionType, Writer
        from mcap_protobuf.schema import register_schema

        self._pb: dict[str, Any] = _messages()
        self._color, self._log, self._scene = Color_pb2.Color, Log_pb2.Log, SceneUpdate_pb2
        self._file = path.open("wb")
        # LZ4 in 256 KiB chunks: each chunk is compressed holding the GIL, so small and fast
        # (zstd over 1 MiB chunks held it for milliseconds: the control loop waited)
        self._writer = Writer(self._file, chunk_size=CHUNK_BYTES, compression=CompressionType.LZ4)
        self._writer.start(profile="", library="cellrunner")
        self._writer.add_metadata("cellrunner", {"recording": name})
        self._register = register_schema
        self._channels: dict[str, int] = {}
        self._pending_meshes: list[Any] = []
        self._plots: dict[str, float] = {}
        self._plots_s: float | None = None
        self._last_ns = 0
        self._tf: list[Any] = []
        self._tf_s = 0.0
        plots_schema = self._writer.register_schema(
            "cellrunner.Plots", "jsonschema", json.dumps(_PLOTS_SCHEMA).encode()
        )
        self._plots_channel = self._writer.register_channel("/plots", "json", plots_schema)

    # -- writing ------------------------------------------------------------------------
    def _write(self, topic: str, message: Any, time_s: float) -> None:
        channel = self._channels.get(topic)
        if channel is None:
            schema = self._register(self._writer, type(message))
            channel = self._writer.register_channel(topic, "protobuf", schema)
            self._channels[topic] = channel
        self._emit(channel, message.SerializeToString(), time_s)

    def _emit(self, channel: int, data: bytes, time_s: float) -> None:
        ns = max(_ns(time_s), self._last_ns)  # log time never goes back
        self._last_ns = ns
        self._writer.add_message(channel, log_time=ns, data=data, publish_time=ns)
        time.sleep(0)  # let a waiting thread (the control loop) have the GIL between messages

    def _timed(self, time_s: float) -> None:
        """Before a message at ``time_s``: the meshes held back, the last sample's plots."""
        if self._pending_meshes:
            update = self._scene.SceneUpdate(entities=self._pending_meshes)
            for entity in update.entities:
                entity.timestamp.FromNanoseconds(_ns(time_s))
            self._write("/scene", update, time_s)
            self._pending_meshes = []
        if self._plots_s is not None and self._plots_s != time_s:
            self._flush_plots()
        if self._tf and self._tf_s != time_s:
            self._flush_tf()

    def _flush_tf(self) -> None:
        """The frames of one sample in one FrameTransforms message."""
        if self._tf:
            self._write("/tf", self._pb["FrameTransforms"](transforms=self._tf), self._tf_s)
            self._tf = []

    def _flush_plots(self) -> None:
        if self._plots_s is None:
            return
        body = json.dumps({"time_s": self._plots_s, **self._plots}).encode()
        self._emit(self._plots_channel, body, self._plots_s)
        self._plots, self._plots_s = {}, None

    def _stamp(self, message: Any, time_s: float) -> None:
        message.timestamp.FromNanoseconds(_ns(time_s))

    # -- the Sink -----------------------------------------------------------------------
    def mesh(self, path: str, vertices_m: np.ndarray, faces: np.ndarray, rgba: Rgba) -> None:
        key = (path, id(vertices_m), len(vertices_m), rgba)
        cached = _MESHES.get(key)
        if cached is not None and cached[0] is vertices_m:
            entity = self._pb["SceneEntity"]()
            entity.CopyFrom(cached[1])
            self._pending_meshes.append(entity)
            return
        pb = self._pb
        triangles = pb["TriangleListPrimitive"](
            pose=pb["Pose"](orientation=pb["Quaternion"](w=1.0)),
            color=self._color(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3]),
        )
        point = pb["Point3"]
        for i in range(0, len(vertices_m), _POINTS_PER_SLICE):  # in slices: the GIL moves
            rows = vertices_m[i : i + _POINTS_PER_SLICE].tolist()
            triangles.points.extend([point(x=x, y=y, z=z) for x, y, z in rows])
            time.sleep(0)
        triangles.indices.extend(np.asarray(faces, np.uint32).ravel().tolist())
        entity = pb["SceneEntity"](
            frame_id=frame_of(path), id=path, frame_locked=True, triangles=[triangles]
        )
        self._pending_meshes.append(entity)
        _MESHES[key] = (vertices_m, entity)

    def pose(self, time_s: float, path: str, T_parent_child: np.ndarray) -> None:
        self._timed(time_s)
        pb = self._pb
        x, y, z, w = quaternion_xyzw(T_parent_child[:3, :3])
        tx, ty, tz = (float(v) for v in T_parent_child[:3, 3])
        transform = pb["FrameTransform"](
            parent_frame_id="world",
            child_frame_id=path.split("/", 1)[1] if "/" in path else path,
            translation=pb["Vector3"](x=tx, y=ty, z=tz),
            rotation=pb["Quaternion"](x=float(x), y=float(y), z=float(z), w=float(w)),
        )
        self._stamp(transform, time_s)
        self._tf.append(transform)
        self._tf_s = time_s

    def line(self, time_s: float, path: str, points_m: np.ndarray, rgba: Rgba) -> None:
        self._timed(time_s)
        pb = self._pb
        strip = pb["LinePrimitive"](
            type=pb["LinePrimitive"].LINE_STRIP,
            pose=pb["Pose"](orientation=pb["Quaternion"](w=1.0)),
            thickness=3.0,
            scale_invariant=True,
            points=[pb["Point3"](x=float(x), y=float(y), z=float(z)) for x, y, z in points_m],
            color=self._color(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3]),
        )
        entity = pb["SceneEntity"](frame_id="world", id=path, lines=[strip])
        self._stamp(entity, time_s)
        self._write("/paths", self._scene.SceneUpdate(entities=[entity]), time_s)

    def points(self, time_s: float, path: str, points_m: np.ndarray, rgba: Rgba) -> None:
        self._timed(time_s)
        pb = self._pb
        field = pb["PackedElementField"]
        cloud = pb["PointCloud"](
            frame_id="world",
            pose=pb["Pose"](orientation=pb["Quaternion"](w=1.0)),
            point_stride=12,
            fields=[field(name=n, offset=4 * i, type=field.FLOAT32) for i, n in enumerate("xyz")],
            data=np.asarray(points_m, "<f4").tobytes(),
        )
        self._stamp(cloud, time_s)
        self._write("/" + path.split("/", 1)[-1], cloud, time_s)

    def scalar(self, time_s: float, path: str, value: float) -> None:
        self._timed(time_s)
        self._plots_s = time_s
        self._plots[path.removeprefix("plots/").replace("/", ".")] = value

    def text(self, time_s: float, path: str, text: str, level: str) -> None:
        self._timed(time_s)
        log = self._log(message=text, name=path, level=getattr(self._log, level, self._log.INFO))
        self._stamp(log, time_s)
        self._write("/log", log, time_s)

    def depth(self, time_s: float, path: str, depth_m: np.ndarray) -> None:
        d = np.nan_to_num(np.asarray(depth_m, "<f4"), posinf=0.0)
        self._raw(time_s, path, d, "32FC1", 4 * d.shape[1])

    def image(self, time_s: float, path: str, rgb: np.ndarray) -> None:
        img = np.asarray(rgb, np.uint8)
        if img.ndim == 2:  # a grey camera
            self._raw(time_s, path, img, "mono8", img.shape[1])
        else:
            self._raw(time_s, path, img, "rgb8", 3 * img.shape[1])

    def _raw(self, time_s: float, path: str, pixels: np.ndarray, encoding: str, step: int) -> None:
        self._timed(time_s)
        image = self._pb["RawImage"](
            frame_id=path.rsplit("/", 1)[0],  # cameras/NAME: the camera's frame in /tf
            width=pixels.shape[1],
            height=pixels.shape[0],
            encoding=encoding,
            step=step,
            data=np.ascontiguousarray(pixels).tobytes(),
        )
        self._stamp(image, time_s)
        self._write("/" + path, image, time_s)

    def close(self) -> None:
        self._timed(self._plots_s if self._plots_s is not None else 0.0)
        self._flush_plots()
        self._flush_tf()
        self._writer.finish()  # type: ignore[no-untyped-call]
        self._file.close()


def _messages() -> dict[str, Any]:
    """Foxglove's message classes by name."""
    import importlib

    names = [
        "FrameTransform",
        "FrameTransforms",
        "LinePrimitive",
        "PackedElementField",
        "Point3",
        "PointCloud",
        "Pose",
        "Quaternion",
        "RawImage",
        "SceneEntity",
        "TriangleListPrimitive",
        "Vector3",
    ]
    module = "foxglove_schemas_protobuf.{}_pb2"
    return {n: getattr(importlib.import_module(module.format(n)), n) for n in names}
