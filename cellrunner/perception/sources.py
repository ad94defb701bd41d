"""Where depth images come from on the arm (SPEC section 12): a small protocol, the twin's
depth cameras over the network, a replay of recorded images, and loading a real camera's
driver by name.

Protocol. A depth source is any object with ``connect()``, ``grab() -> DepthImage`` and
``close()``, made by a factory ``FACTORY(name: str, camera: Camera, host: str | None)``;
``run``/``serve --depth-source my_package.my_module:make_depth`` loads it. ``grab``
returns the newest image (blocking at most about one frame period): depths in metres
along the camera's Z (H x W float32, 0 where the camera measured nothing), in the frame
of the camera block (its pose, mount and intrinsics; a driver registers depth to that
camera first), with the intrinsics of that image. Built in:

- ``twin``: the depth cameras of ``cellrunner twin`` on the robot host (port 29991);
- ``replay:DIR``: the files ``DIR/NAME/*.npy`` (H x W float32 depths in m) in name order,
  one per ``1/rate`` s, looping: a recorded stream played back.
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np

from cellrunner.errors import CellrunnerError, UsageError
from cellrunner.model.camera import Camera
from cellrunner.vision.images import TwinCamera


@dataclass(frozen=True, eq=False)
class DepthImage:
    """One depth image: ``depth_m`` (H x W float32, m, 0 = none) and its intrinsics
    ``K`` (3 x 3, px)."""

    depth_m: np.ndarray
    K: np.ndarray


class DepthSource(Protocol):
    """A depth camera: construct (no I/O), ``connect()``, ``grab()``, ``close()``."""

    def connect(self) -> None: ...

    def grab(self) -> DepthImage: ...

    def close(self) -> None: ...


class DepthError(CellrunnerError):
    """A depth camera answered, but not with a depth image."""


class TwinDepthCamera(TwinCamera):
    """Depth camera ``name`` of a ``cellrunner twin`` at ``host``."""

    def grab(self) -> DepthImage:  # type: ignore[override]  # a depth image, not a picture
        if self._sock is None:
            raise DepthError("grab before connect")
        try:
            self._sock.sendall(f"depth {self.name}\n".encode())
            header = self._read_line().split()
            if header[:1] != ["ok"]:
                raise DepthError(f"twin depth camera {self.name}: {' '.join(header[1:])}")
            width, height = int(header[1]), int(header[2])
            fx, fy, cx, cy = (float(v) for v in header[5:9])
            data = self._read_exact(width * height * 4)
        except OSError as exc:
            raise DepthError(f"lost the twin depth camera at {self.host}: {exc}") from None
        depth = np.frombuffer(data, "<f4").reshape(height, width).astype(np.float32)
        return DepthImage(depth, np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]]))


class ReplayDepth:
    """Recorded depth images ``DIR/NAME/*.npy`` in name order, one per ``1/rate`` s
    (looping); the camera block's intrinsics."""

    def __init__(self, directory: Path, name: str, camera: Camera) -> None:
        self.directory, self.name, self.camera = Path(directory) / name, name, camera
        self.rate_hz = camera.depth.rate if camera.depth is not None else 15.0
        self._files: list[Path] = []
        self._next = 0
        self._due = 0.0

    def connect(self) -> None:
        self._files = sorted(self.directory.glob("*.npy"))
        if not self._files:
            raise UsageError(f"--depth-source replay: no *.npy files in {self.directory}")

    def grab(self) -> DepthImage:
        wait = self._due - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        self._due = max(self._due, time.monotonic()) + 1.0 / self.rate_hz
        path = self._files[self._next % len(self._files)]
        self._next += 1
        depth = np.asarray(np.load(path), np.float32)
        w, h = self.camera.image_size
        if depth.shape != (h, w):
            raise DepthError(
                f"{path}: {depth.shape[1]} x {depth.shape[0]} px, the camera has {w} x {h}"
            )
        return DepthImage(depth, self.camera.intrinsics.matrix())

    def close(self) -> None:
        self._files = []


def depth_source(spec: str | None, name: str, camera: Camera, host: str | None) -> DepthSource:
    """The depth source ``spec`` names (module docstring): None or ``twin``, ``replay:DIR``,
    or ``MODULE:FACTORY``."""
    if spec in (None, "twin"):
        if not host:
            raise UsageError("give --robot-host H: the twin's depth cameras are served there")
        return TwinDepthCamera(name, host)
    kind, _, rest = spec.partition(":")
    if kind == "replay":
        if not rest:
            raise UsageError(f"--depth-source {spec!r}: give replay:DIR")
        return ReplayDepth(Path(rest), name, camera)
    if not kind or not rest:
        raise UsageError(f"--depth-source {spec!r}: give twin, replay:DIR, or MODULE:FACTORY")
    try:
        factory: Callable[..., DepthSource] = getattr(importlib.import_module(kind), rest)
    except (ImportError, AttributeError) as exc:
        raise UsageError(f"--depth-source {spec!r}: cannot load it ({exc})") from None
    return factory(name, camera, host)
