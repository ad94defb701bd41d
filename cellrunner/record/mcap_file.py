"""A :class:`~cellrunner.record.sink.Sink` writing MCAP that Foxglove opens as a robot's
log: Foxglove's well-known schemas in protobuf (``foxglove-schemas-protobuf``, published
by Foxglove with the schemas, written with ``mcap`` and ``mcap-protobuf-support``):

    /tf                  foxglove.FrameTransforms   each body's frame in ``world``, the TCP
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
        self._writer = Writer(self._file, compression=CompressionType.ZSTD)
        self._writer.start(profile="", library="cellrunner")
        self._writer.add_metadata("cellrunner", {"recording": name})
        self._register = register_schema
        self._channels: dict[str, int] = {}
        self._pending_meshes: list[Any] = []
        self._plots: dict[str, float] = {}
        self._plots_s: float | None = None
        self._last_ns = 0
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
        pb = self._pb
        triangles = pb["TriangleListPrimitive"](
            pose=pb["Pose"](orientation=pb["Quaternion"](w=1.0)),
            points=[pb["Point3"](x=float(x), y=float(y), z=float(z)) for x, y, z in vertices_m],
            color=self._color(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3]),
            indices=[int(i) for i in np.asarray(faces).ravel()],
        )
        entity = pb["SceneEntity"](
            frame_id=frame_of(path), id=path, frame_locked=True, triangles=[triangles]
        )
        self._pending_meshes.append(entity)

    def pose(self, time_s: float, path: str, T_parent_child: np.ndarray) -> None:
        from scipy.spatial.transform import Rotation

        self._timed(time_s)
        pb = self._pb
        x, y, z, w = Rotation.from_matrix(T_parent_child[:3, :3]).as_quat()
        tx, ty, tz = (float(v) for v in T_parent_child[:3, 3])
        transform = pb["FrameTransform"](
            parent_frame_id="world",
            child_frame_id=path.split("/", 1)[1] if "/" in path else path,
            translation=pb["Vector3"](x=tx, y=ty, z=tz),
            rotation=pb["Quaternion"](x=float(x), y=float(y), z=float(z), w=float(w)),
        )
        self._stamp(transform, time_s)
        self._write("/tf", pb["FrameTransforms"](transforms=[transform]), time_s)

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
        self._raw(time_s, path, img, "rgb8", 3 * img.shape[1])

    def _raw(self, time_s: float, path: str, pixels: np.ndarray, encoding: str, step: int) -> None:
        self._timed(time_s)
        image = self._pb["RawImage"](
            frame_id=path.split("/")[1] if "/" in path else path,
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
