"""Reading STL meshes (binary or ASCII): the one reader of the package.

Collision models and plots take vertices and triangles (:func:`read_stl`), the twin's
MuJoCo model takes the file as binary STL bytes (:func:`binary_stl`) and triangle corners
(:func:`stl_triangles`). A file that is not STL raises ValueError naming the file.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

#: one binary STL triangle: normal, three corners, attribute byte count
_RECORD = np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])


def read_stl(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V x 3, file units) and triangles (T x 3 indices) of a binary or ASCII STL."""
    corners = _corners(Path(path).read_bytes(), path).reshape(-1, 3)
    vertices, inverse = np.unique(corners, axis=0, return_inverse=True)
    return vertices, inverse.reshape(-1, 3).astype(int)


def stl_triangles(path: Path) -> np.ndarray:
    """(n, 3, 3) triangle corners (file units) of a binary or ASCII STL, as MuJoCo reads
    them (single precision)."""
    raw = binary_stl(path)
    count = struct.unpack_from("<I", raw, 80)[0]
    return np.frombuffer(raw, dtype=_RECORD, count=count, offset=84)["v"].astype(float)


def binary_stl(path: Path) -> bytes:
    """The bytes of STL file ``path`` in binary form (MuJoCo reads only binary STL): a
    binary file as it is, an ASCII one written out.

    Raises ValueError naming the file when it cannot be read or parsed."""
    try:
        raw = Path(path).read_bytes()
    except OSError as exc:
        raise ValueError(f"cannot read mesh {path}: {exc.strerror}") from exc
    if _is_binary(raw):
        return raw
    corners = _corners(raw, path)
    records = np.zeros(len(corners), dtype=_RECORD)
    records["v"] = corners
    return bytes(bytearray(80) + struct.pack("<I", len(corners)) + records.tobytes())


def _is_binary(raw: bytes) -> bool:
    return len(raw) >= 84 and len(raw) == 84 + 50 * struct.unpack_from("<I", raw, 80)[0]


def _corners(raw: bytes, path: Path) -> np.ndarray:
    """(n, 3, 3) triangle corners of the STL file ``raw``, read from ``path``."""
    if _is_binary(raw):
        count = struct.unpack_from("<I", raw, 80)[0]
        return np.frombuffer(raw, dtype=_RECORD, count=count, offset=84)["v"].astype(float)
    text = raw.decode("ascii", errors="replace")
    vertices = [
        [float(v) for v in line.split()[1:4]]
        for line in text.splitlines()
        if line.strip().lower().startswith("vertex")
    ]
    if not vertices and not text.lstrip().lower().startswith("solid"):
        raise ValueError(f"mesh {path} is neither a binary nor an ASCII STL file")
    if not vertices or len(vertices) % 3:
        raise ValueError(f"mesh {path}: ASCII STL with {len(vertices)} vertices, not triangles")
    return np.array(vertices, dtype=float).reshape(-1, 3, 3)
