"""Where pictures come from: a small :class:`ImageSource` protocol, the twin's rendered
cameras (:class:`TwinCamera`), and loading a real camera's driver by name.

A real camera plugs in as any object with ``connect()``, ``grab() -> ndarray`` (H x W x 3
RGB or H x W grey, uint8, at the camera block's image size and intrinsics) and
``close()``, made by a factory ``factory(name: str, camera: Camera, host: str | None)``;
``calibrate-camera --image-source my_package.my_module:make_camera`` loads it.
"""

from __future__ import annotations

import importlib
import socket
from collections.abc import Callable
from typing import Protocol

import numpy as np

from cellrunner.errors import CellrunnerError, PeerUnreachable, UsageError
from cellrunner.model.camera import Camera

#: the twin's camera port (cellrunner.twin.camera; kept here so no twin import is needed)
TWIN_CAMERA_PORT = 29991


class ImageError(CellrunnerError):
    """A camera answered, but not with a picture."""


class ImageSource(Protocol):
    """A camera: construct (no I/O), ``connect()``, ``grab()`` as often as needed,
    ``close()``."""

    def connect(self) -> None: ...

    def grab(self) -> np.ndarray:
        """One picture, taken now: H x W x 3 RGB or H x W grey, uint8."""
        ...

    def close(self) -> None: ...


class TwinCamera:
    """Camera ``name`` of a ``cellrunner twin`` at ``host`` (port 29991)."""

    def __init__(self, name: str, host: str, port: int = TWIN_CAMERA_PORT, timeout_s: float = 30.0):
        self.name, self.host, self.port, self.timeout_s = name, host, port, timeout_s
        self._sock: socket.socket | None = None
        self._buffer = b""

    def connect(self) -> None:
        try:
            self._sock = socket.create_connection((self.host, self.port), timeout=self.timeout_s)
        except OSError as exc:
            raise PeerUnreachable(
                f"no twin camera server at {self.host}:{self.port} ({exc.strerror or exc}); "
                "is `cellrunner twin` running with this camera in its cell?"
            ) from None

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def grab(self) -> np.ndarray:
        if self._sock is None:
            raise ImageError("grab before connect")
        try:
            self._sock.sendall(f"grab {self.name}\n".encode())
            header = self._read_line().split()
            if header[:1] != ["ok"]:
                raise ImageError(f"twin camera {self.name}: {' '.join(header[1:])}")
            width, height, channels = (int(v) for v in header[1:4])
            data = self._read_exact(width * height * channels)
        except OSError as exc:
            raise PeerUnreachable(f"lost the twin camera at {self.host}: {exc}") from None
        return np.frombuffer(data, np.uint8).reshape(height, width, channels)

    def _read_line(self) -> str:
        while b"\n" not in self._buffer:
            self._fill()
        line, self._buffer = self._buffer.split(b"\n", 1)
        return line.decode(errors="replace")

    def _read_exact(self, n: int) -> bytes:
        while len(self._buffer) < n:
            self._fill()
        data, self._buffer = self._buffer[:n], self._buffer[n:]
        return data

    def _fill(self) -> None:
        assert self._sock is not None  # reads follow connect()
        chunk = self._sock.recv(1 << 20)
        if not chunk:
            raise OSError("the twin closed the connection")
        self._buffer += chunk


def image_source(spec: str | None, name: str, camera: Camera, host: str | None) -> ImageSource:
    """The image source ``spec`` names: None or ``twin`` for the twin's camera on ``host``;
    ``MODULE:FACTORY`` for a driver (``FACTORY(name, camera, host)`` returns the source)."""
    if spec in (None, "twin"):
        if not host:
            raise UsageError("give --robot-host H: the twin's cameras are served there")
        return TwinCamera(name, host)
    module_name, _, attr = spec.partition(":")
    if not module_name or not attr:
        raise UsageError(f"--image-source {spec!r}: give twin, or MODULE:FACTORY")
    try:
        factory: Callable[..., ImageSource] = getattr(importlib.import_module(module_name), attr)
    except (ImportError, AttributeError) as exc:
        raise UsageError(f"--image-source {spec!r}: cannot load it ({exc})") from None
    return factory(name, camera, host)


class CameraFeeds:
    """Every camera of a cell through one image source ``spec`` (see :func:`image_source`),
    each connected on its first :meth:`grab`; :meth:`close` closes them all."""

    def __init__(self, spec: str | None, cameras: dict[str, Camera], host: str | None) -> None:
        self.spec, self.cameras, self.host = spec, cameras, host
        self._open: dict[str, ImageSource] = {}

    def grab(self, name: str) -> np.ndarray:
        if name not in self._open:
            source = image_source(self.spec, name, self.cameras[name], self.host)
            source.connect()
            self._open[name] = source
        return self._open[name].grab()

    def close(self) -> None:
        for source in self._open.values():
            source.close()
        self._open.clear()
