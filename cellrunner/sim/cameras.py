"""The cell's cameras in the MuJoCo twin: a MuJoCo camera where each camera is, its
calibration board as a textured slab, and rendering what the camera sees.

MuJoCo renders an ideal pinhole (square pixels, principal point at the image centre, no
distortion) with the camera's ``fovy``; :class:`CameraImager` then resamples that picture
through the camera's real intrinsics and distortion (OpenCV's model), so the image is the
one the camera block describes, pixel for pixel. Pixel centres are at integer coordinates
(OpenCV's convention): the ideal picture's centre is at ((W-1)/2, (H-1)/2).

MuJoCo's camera looks along its -Z with Y up; the cell's camera frame is OpenCV's (Z out
of the lens, Y down): the two differ by a half turn about X.
"""

from __future__ import annotations

import io
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import Any

import numpy as np

#: the camera frame (OpenCV) -> MuJoCo's camera frame
T_CV_MJ = np.diag([1.0, -1.0, -1.0, 1.0])
#: board slab thickness (m); its printed face is the slab's top at z = 0
BOARD_THICKNESS_M = 0.003


@dataclass(frozen=True, eq=False)
class BoardDescription:
    """A calibration board: its printed sheet (a grey picture, sheet +Y edge in row 0) of
    ``size_m`` (width, height) centred on the board frame, at ``T_parent_board``."""

    on_flange: bool
    T_parent_board: np.ndarray
    size_m: tuple[float, float]
    picture: np.ndarray


@dataclass(frozen=True, eq=False)
class MarkerDescription:
    """An ArUco marker printed on part ``part`` (on a fixture when ``part`` is '': then
    ``T_part_marker`` is in the world; see :mod:`cellrunner.vision.marker`): its sheet
    (grey, marker +Y edge in row 0) of ``size_m`` square, centred on the marker frame at
    ``T_part_marker``."""

    part: str
    key: str
    T_part_marker: np.ndarray
    size_m: float
    picture: np.ndarray


@dataclass(frozen=True, eq=False)
class CameraDescription:
    """A camera at ``T_parent_camera`` (camera frame as OpenCV's; parent: the world, or the
    flange when ``on_flange``), with its image size and intrinsics."""

    name: str
    on_flange: bool
    T_parent_camera: np.ndarray
    width: int
    height: int
    K: np.ndarray
    distortion: np.ndarray
    board: BoardDescription | None = None

    @property
    def f_ideal_px(self) -> float:
        """Focal length of the ideal picture MuJoCo renders (the camera's fy)."""
        return float(self.K[1, 1])

    @property
    def fovy_deg(self) -> float:
        return math.degrees(2 * math.atan(self.height / 2 / self.f_ideal_px))


def describe_cameras(loaded: Any) -> tuple[CameraDescription, ...]:
    """The cell's cameras (world or frame mounts resolved to the world)."""
    from cellrunner.model.camera import FLANGE
    from cellrunner.model.expand import frame_pose

    def parent(mount: str, T: np.ndarray) -> tuple[bool, np.ndarray]:
        if mount == FLANGE:
            return True, T
        return False, frame_pose(loaded.cell, mount) @ T

    out = []
    for name, cam in loaded.cell.cameras.items():
        board = None
        if cam.board is not None:
            from cellrunner.vision.board import picture, printed_size_m

            on_flange, T = parent(cam.board.mount, cam.board.pose.matrix())
            board = BoardDescription(on_flange, T, printed_size_m(cam.board), picture(cam.board))
        on_flange, T = parent(cam.mount, cam.pose.matrix())
        out.append(
            CameraDescription(
                name,
                on_flange,
                T,
                cam.image_size[0],
                cam.image_size[1],
                cam.intrinsics.matrix(),
                np.asarray(cam.intrinsics.distortion, float),
                board,
            )
        )
    return tuple(out)


def _png(grey: np.ndarray) -> bytes:
    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(grey).save(buffer, format="PNG")
    return buffer.getvalue()


def add_cameras(
    builder: Any,
    cameras: tuple[CameraDescription, ...],
    markers: tuple[MarkerDescription, ...] = (),
) -> None:
    """Add each camera, each board and each part's marker as a textured slab, to the MJCF
    being built (world mounts in the worldbody, flange mounts in the ``tool`` body, markers
    in their part's body)."""
    from cellrunner.sim.mjcf_attrs import pose_attrs as _pose_attrs

    root = builder.root
    world = root.find("worldbody")
    tool = next(b for b in root.iter("body") if b.get("name") == "tool")
    biggest = [max([1600, *(c.width for c in cameras)]), max([1200, *(c.height for c in cameras)])]
    glob = root.find("visual/global")
    glob.set("offwidth", str(biggest[0]))
    glob.set("offheight", str(biggest[1]))
    for cam in cameras:
        parent = tool if cam.on_flange else world
        ET.SubElement(
            parent,
            "camera",
            name=f"camera:{cam.name}",
            mode="fixed",
            fovy=f"{cam.fovy_deg:.9g}",
            **_pose_attrs(cam.T_parent_camera @ T_CV_MJ),
        )
        b = cam.board
        if b is not None:
            _add_sheet(
                builder,
                tool if b.on_flange else world,
                f"board-{cam.name}",
                f"board:{cam.name}",
                b.picture,
                b.size_m,
                b.T_parent_board,
            )
    bodies = {b.get("name"): b for b in root.iter("body")}
    for m in markers:
        _add_sheet(
            builder,
            bodies[f"part:{m.part}"] if m.part else world,
            f"marker-{m.key}",
            f"marker:{m.key}",
            m.picture,
            (m.size_m, m.size_m),
            m.T_part_marker,
        )


def _add_sheet(
    builder: Any,
    parent: Any,
    key: str,
    name: str,
    picture: np.ndarray,
    size_m: tuple[float, float],
    T_parent_sheet: np.ndarray,
) -> None:
    """A printed sheet (a textured slab, its printed face at z = 0 facing +Z, picture row
    0 at its +Y edge) of ``size_m`` (width, height) centred at ``T_parent_sheet``; it
    neither collides nor weighs."""
    from cellrunner.sim.mjcf_attrs import fmt as _fmt
    from cellrunner.sim.mjcf_attrs import pose_attrs as _pose_attrs

    builder.mesh_files[f"{key}.png"] = _png(picture)
    ET.SubElement(builder.assets, "texture", name=key, type="2d", file=f"{key}.png")
    ET.SubElement(
        builder.assets,
        "material",
        name=key,
        texture=key,
        specular="0",
        shininess="0",
        reflectance="0",
        emission="0.4",
    )
    w, h, t = size_m[0] / 2, size_m[1] / 2, BOARD_THICKNESS_M
    corners = [(-w, h), (w, h), (w, -h), (-w, -h)]  # picture: top left, clockwise
    vertices = [(x, y, 0.0) for x, y in corners] + [(x, y, -t) for x, y in corners]
    uv = [(0, 0), (1, 0), (1, 1), (0, 1)] * 2
    faces = [
        (0, 3, 2), (0, 2, 1),  # printed face, counter-clockwise seen from +Z
        (4, 5, 6), (4, 6, 7),
        (0, 1, 5), (0, 5, 4), (1, 2, 6), (1, 6, 5),
        (2, 3, 7), (2, 7, 6), (3, 0, 4), (3, 4, 7),
    ]  # fmt: skip
    ET.SubElement(
        builder.assets,
        "mesh",
        name=key,
        vertex=_fmt(vertices),
        texcoord=_fmt(uv),
        face=" ".join(str(i) for f in faces for i in f),
    )
    ET.SubElement(
        parent,
        "geom",
        name=name,
        type="mesh",
        mesh=key,
        material=key,
        contype="0",
        conaffinity="0",
        density="0",
        **_pose_attrs(T_parent_sheet),
    )


class CameraImager:
    """Renders a camera of a compiled twin model: ``image(qpos)`` is what it sees with the
    arm at ``qpos`` (RGB, height x width x 3, uint8). Holds a GL context: use it on one
    thread, and ``close()`` it."""

    def __init__(self, model: Any, camera: CameraDescription):
        from cellrunner.sim.mujoco_loader import load_mujoco

        self._mj = load_mujoco()
        self.model, self.camera = model, camera
        self.data = self._mj.MjData(model)
        self._renderer: Any = None
        self._map = _ideal_map(camera)
        self._options = self._mj.MjvOption()
        self._options.sitegroup[:] = 0  # sites (the TCP marker, sensors) are not physical

    def image(self, qpos: np.ndarray) -> np.ndarray:
        from cellrunner.sim.render import RenderUnavailable

        if self._renderer is None:
            from cellrunner.sim.mujoco_loader import GL_ADVICE, gl_backend, no_gl_reason

            if gl_backend() is None:
                raise RenderUnavailable(
                    f"cannot render camera {self.camera.name}: {no_gl_reason()} "
                    f"({GL_ADVICE} gives pictures)"
                )
            try:
                self._renderer = self._mj.Renderer(
                    self.model, self.camera.height, self.camera.width
                )
            except Exception as exc:  # GL backends fail with many exception types
                raise RenderUnavailable(f"cannot render camera {self.camera.name}: {exc}") from exc
        self.data.qpos[:] = qpos
        self._mj.mj_kinematics(self.model, self.data)
        self._mj.mj_camlight(self.model, self.data)
        self._renderer.update_scene(
            self.data, camera=f"camera:{self.camera.name}", scene_option=self._options
        )
        ideal = np.array(self._renderer.render())
        if self._map is None:
            return ideal
        import cv2

        return cv2.remap(ideal, self._map[0], self._map[1], cv2.INTER_LINEAR)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


def _ideal_map(camera: CameraDescription) -> tuple[np.ndarray, np.ndarray] | None:
    """For every pixel of the camera's image, where it lies in the ideal picture; None
    when the camera is the ideal one."""
    W, H, K, f = camera.width, camera.height, camera.K, camera.f_ideal_px
    ideal = (
        abs(K[0, 0] - f) < 1e-9
        and abs(K[0, 2] - (W - 1) / 2) < 1e-9
        and abs(K[1, 2] - (H - 1) / 2) < 1e-9
        and not np.any(camera.distortion)
    )
    if ideal:
        return None
    import cv2

    u, v = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    pixels = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-10)
    # OpenCV's stubs do not allow None for R and P (no rectification), its bindings do
    rays = cv2.undistortPointsIter(pixels, K, camera.distortion, None, None, criteria)  # type: ignore[call-overload]
    rays = rays.reshape(-1, 2)
    map_x = (f * rays[:, 0] + (W - 1) / 2).reshape(H, W).astype(np.float32)
    map_y = (f * rays[:, 1] + (H - 1) / 2).reshape(H, W).astype(np.float32)
    return map_x, map_y
