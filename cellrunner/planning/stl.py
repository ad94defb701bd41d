"""Reading STL meshes (binary or ASCII) into vertices and triangles."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def read_stl(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V x 3, file units) and triangles (T x 3 indices) of a binary or ASCII STL."""
    raw = Path(path).read_bytes()
    if len(raw) >= 84:
        count = int(np.frombuffer(raw, dtype="<u4", count=1, offset=80)[0])
        if 84 + 50 * count == len(raw):
            record = np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
            corners = np.frombuffer(raw, dtype=record, count=count, offset=84)["v"].reshape(-1, 3)
            return _dedupe(corners.astype(float))
    text = raw.decode("ascii", errors="replace")
    vertex_lines = [
        [float(v) for v in line.split()[1:4]]
        for line in text.splitlines()
        if line.strip().startswith("vertex")
    ]
    if not vertex_lines or len(vertex_lines) % 3:
        raise ValueError(f"{path}: not an STL file (no triangles found)")
    return _dedupe(np.array(vertex_lines, dtype=float))


def _dedupe(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    vertices, inverse = np.unique(corners, axis=0, return_inverse=True)
    return vertices, inverse.reshape(-1, 3).astype(int)
