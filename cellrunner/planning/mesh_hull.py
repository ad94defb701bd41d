"""Which meshes collide as their convex hull, in check and in the twin alike.

MuJoCo collides a mesh as its convex hull; a static mesh that does not fill its hull is
built in the twin as its surfaces instead (``cellrunner/sim/mesh_pieces.py``). ``check``
takes the same decision from the same rule: a convex mesh is a coal convex polytope, whose
overlap with a part is measured as a depth (a pin pressed 0.7 mm into a chamfered wall
named in ``contact:`` is a jam), and a mesh that is not convex stays a triangle surface.
"""

from __future__ import annotations

import numpy as np

#: a mesh whose hull is this much larger than the mesh (by volume) is not convex
HULL_EXCESS = 1.02


def convexity(triangles: np.ndarray) -> bool | None:
    """Whether the closed mesh of ``triangles`` ((n, 3, 3) corners) fills its convex hull
    (volumes within :data:`HULL_EXCESS`; an open one, enclosing nothing, does not); None
    when its hull has no volume (flat or degenerate)."""
    from scipy.spatial import ConvexHull, QhullError

    triangles = np.asarray(triangles, float)
    if not len(triangles):
        return None
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    volume = abs(float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum()) / 6.0)
    try:
        hull = ConvexHull(triangles.reshape(-1, 3)).volume
    except QhullError:  # flat or degenerate: no hull to fill
        return None
    return bool(volume > 0 and hull <= HULL_EXCESS * volume)
