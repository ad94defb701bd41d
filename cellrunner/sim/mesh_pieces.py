"""Non-convex mesh fixtures in the twin: MuJoCo collides a mesh as its convex hull, which
fills a hole a peg should go into. A static mesh that is not convex is built instead as
one thin convex prism per triangle (the triangle pushed ``PRISM_DEPTH_M`` into the solid
along its inward normal), so its surfaces are where the file puts them.
"""

from __future__ import annotations

import numpy as np

#: how far each triangle's prism reaches into the solid (m)
PRISM_DEPTH_M = 0.002
#: a mesh whose hull is this much larger than the mesh (by volume) is not convex
HULL_EXCESS = 1.02
#: meshes with more triangles than this stay hulls (a prism per triangle would be too many geoms)
MAX_TRIANGLES = 3000


def is_convex(triangles: np.ndarray) -> bool:
    """Whether the closed mesh fills its convex hull (volumes within HULL_EXCESS)."""
    from scipy.spatial import ConvexHull

    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    volume = abs(float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum()) / 6.0)
    try:
        hull = ConvexHull(triangles.reshape(-1, 3)).volume
    except Exception:  # flat or degenerate: the caller's flat-mesh rule applies
        return True
    return volume > 0 and hull <= HULL_EXCESS * volume


def prisms(triangles: np.ndarray) -> list[np.ndarray]:
    """One (6, 3) vertex array per non-degenerate triangle: the triangle and its copy
    pushed inward (against its outward, right-handed normal)."""
    out = []
    for tri in triangles:
        n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
        norm = float(np.linalg.norm(n))
        if norm < 1e-12:
            continue
        inner = tri - n / norm * PRISM_DEPTH_M
        out.append(np.vstack([tri, inner]))
    return out
