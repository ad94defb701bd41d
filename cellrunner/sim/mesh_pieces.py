"""Non-convex mesh fixtures in the twin: MuJoCo collides a mesh as its convex hull, which
fills a hole a peg should go into. A static mesh that is not convex is built instead as
one thin convex prism per triangle (the triangle pushed ``PRISM_DEPTH_M`` into the solid
along its inward normal), so its surfaces are where the file puts them.
"""

from __future__ import annotations

import numpy as np

#: how far each triangle's prism reaches into the solid (m)
PRISM_DEPTH_M = 0.002
#: meshes with more triangles than this stay hulls (a prism per triangle would be too many geoms)
MAX_TRIANGLES = 3000


def is_convex(triangles: np.ndarray) -> bool:
    """Whether the closed mesh fills its convex hull, as check decides it
    (:func:`cellrunner.planning.mesh_hull.convexity`); a flat or degenerate one counts as
    convex (the caller's flat-mesh rule applies)."""
    from cellrunner.planning.mesh_hull import convexity

    return convexity(triangles) is not False


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
