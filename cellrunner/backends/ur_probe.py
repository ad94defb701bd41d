"""Ask a UR controller what it is, over RTDE, before any ur_rtde client touches it.

ur_rtde reads the controller version but does not expose it, and its connect calls
block for seconds on an unreachable host; this probe is one short, bounded exchange:
RTDE ``request protocol version`` then ``get URControl version``.
"""

from __future__ import annotations

import socket
import struct

from cellrunner.backends.ur_io import recv_exact
from cellrunner.errors import PeerUnreachable

RTDE_PORT = 30004


def _read_message(sock: socket.socket) -> tuple[int, bytes]:
    size, kind = struct.unpack(">HB", recv_exact(sock, 3))
    return kind, recv_exact(sock, size - 3)


def controller_version(
    host: str, timeout_s: float = 3.0, port: int = RTDE_PORT
) -> tuple[int, int, int, int]:
    """``(major, minor, bugfix, build)`` of the controller at ``host``.

    Major 3 is a CB3 controller (PolyScope 3), 5 an e-Series (PolyScope 5), 10 an
    e-Series under PolyScope X. Raises :class:`PeerUnreachable` when it does not answer.
    """
    try:
        with socket.create_connection((host, port), timeout=timeout_s) as sock:
            sock.sendall(struct.pack(">HBH", 5, ord("V"), 2))
            kind, body = _read_message(sock)
            if kind != ord("V") or not body or body[0] != 1:
                raise PeerUnreachable(
                    f"controller at {host}:{port} refused RTDE protocol version 2"
                )
            sock.sendall(struct.pack(">HB", 3, ord("v")))
            kind, body = _read_message(sock)
            if kind != ord("v") or len(body) < 16:
                raise PeerUnreachable(f"controller at {host}:{port} sent no URControl version")
            return struct.unpack(">IIII", body[:16])
    except (OSError, ConnectionError) as exc:
        raise PeerUnreachable(f"cannot reach the robot controller at {host}:{port}: {exc}") from exc


def generation_of(versions: tuple[int, ...]) -> str:
    """``"CB3"`` or ``"e-Series"`` from a controller version (as RobotSpec.generation)."""
    return "CB3" if versions[0] < 5 else "e-Series"
