"""The twin's cameras on the network: TCP port 29991 (not a UR port) on the twin's host
renders what a cell camera sees with the arm where it stands.

Protocol, one request line, one reply:

- ``list`` -> ``ok NAME ...``
- ``grab NAME`` -> ``ok WIDTH HEIGHT 3`` then WIDTH x HEIGHT x 3 bytes, RGB, row by row
- ``depth NAME`` (a depth camera, SPEC section 12) -> ``ok WIDTH HEIGHT 4 TIME_S FX FY CX
  CY`` then WIDTH x HEIGHT float32 little-endian depths in m along the camera's Z (0: no
  depth), row by row; TIME_S is the twin's simulated time when it was taken, FX..CY the
  intrinsics of this image (a GL-less twin casts rays at a reduced resolution)
- anything wrong -> ``error MESSAGE``

One thread serves one client at a time and owns the GL contexts (rendering must stay on
the thread that made them). The arm's joints are copied from the physics under its lock
and rendered in a private MjData, so the real-time loop never waits for a picture.
"""

from __future__ import annotations

import socket
import threading
from typing import Any

import numpy as np

CAMERA_PORT = 29991
#: a request line longer than this is refused (bytes)
MAX_LINE = 256


class CameraServer:
    """Construct with the twin's :class:`~cellrunner.twin.mujoco_physics.MujocoPhysics`,
    ``start()``, ``stop()``."""

    def __init__(self, physics: Any, host: str, port: int = CAMERA_PORT):
        self.physics, self.host, self.port = physics, host, port
        self.cameras = {c.name: c for c in physics.description.cameras}
        self._stop = threading.Event()
        self._listener: socket.socket | None = None
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        listener.bind((self.host, self.port))
        listener.listen(4)
        listener.settimeout(0.2)
        self._listener = listener
        self._thread = threading.Thread(target=self._serve, name="twin-camera", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        if self._listener is not None:
            self._listener.close()

    def _serve(self) -> None:
        imagers: dict[str, Any] = {}
        try:
            while not self._stop.is_set():
                try:
                    assert self._listener is not None  # serving starts after listening
                    conn, _ = self._listener.accept()
                except TimeoutError:
                    continue
                except OSError:
                    return
                with conn:
                    conn.settimeout(30.0)
                    self._client(conn, imagers)
        finally:
            for imager in imagers.values():
                imager.close()

    def _client(self, conn: socket.socket, imagers: dict[str, Any]) -> None:
        buffer = b""
        while not self._stop.is_set():
            try:
                chunk = conn.recv(4096)
            except OSError:
                return
            if not chunk:
                return
            buffer += chunk
            while b"\n" in buffer:
                line, buffer = buffer.split(b"\n", 1)
                try:
                    conn.sendall(self._reply(line.decode(errors="replace").split(), imagers))
                except OSError:
                    return
            if len(buffer) > MAX_LINE:
                conn.sendall(b"error request line too long\n")
                return

    def _reply(self, words: list[str], imagers: dict[str, Any]) -> bytes:
        if words == ["list"]:
            return ("ok " + " ".join(self.cameras) + "\n").encode()
        if len(words) == 2 and words[0] == "depth":
            return self._depth(words[1], imagers)
        if len(words) != 2 or words[0] != "grab":
            return b"error requests: list | grab NAME | depth NAME\n"
        name = words[1]
        if name not in self.cameras:
            known = ", ".join(self.cameras) or "(none)"
            return f"error unknown camera {name!r}; known: {known}\n".encode()
        try:
            if name not in imagers:
                from cellrunner.sim.cameras import CameraImager

                imagers[name] = CameraImager(self.physics.world.model, self.cameras[name])
            image = imagers[name].image(self.physics.snapshot_qpos())
        except Exception as exc:  # rendering fails in GL-specific ways: report, keep serving
            return f"error cannot render camera {name}: {exc}\n".encode()
        height, width = image.shape[:2]
        pixels = np.ascontiguousarray(image, dtype=np.uint8).tobytes()
        return f"ok {width} {height} 3\n".encode() + pixels

    def _depth(self, name: str, imagers: dict[str, Any]) -> bytes:
        description = self.physics.description
        ranges = {n: (near, far) for n, near, far, _ in description.depth}
        if name not in ranges:
            known = ", ".join(ranges) or "(none)"
            return f"error no depth camera {name!r}; depth cameras: {known}\n".encode()
        key = f"depth:{name}"
        try:
            if key not in imagers:
                from cellrunner.sim.depth import DepthImager

                imagers[key] = DepthImager(
                    self.physics.world.model,
                    self.cameras[name],
                    ranges[name],
                    description.depth_noise_m,
                )
            qpos, mocap_pos, mocap_quat, time_s = self.physics.snapshot_scene()
            frame = imagers[key].frame(qpos, mocap_pos, mocap_quat, time_s)
        except Exception as exc:  # rendering fails in GL-specific ways: report, keep serving
            return f"error cannot render depth camera {name}: {exc}\n".encode()
        height, width = frame.depth_m.shape
        K = frame.K
        header = (
            f"ok {width} {height} 4 {time_s:.6f} {K[0, 0]:.9g} {K[1, 1]:.9g} "
            f"{K[0, 2]:.9g} {K[1, 2]:.9g}\n"
        )
        return header.encode() + np.ascontiguousarray(frame.depth_m, "<f4").tobytes()
