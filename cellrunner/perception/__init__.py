"""Perception: depth images turned into a live obstacle map of the watched zone (SPEC
section 12), and the questions asked of it.

- :mod:`.frames`: a depth image with its camera and capture time, back-projected to points.
- :mod:`.solids`: convex solids that answer "which of these points lie within ``pad`` of
  me" (boxes, cylinders, spheres, hulls; the arm's convex parts).
- :mod:`.known`: what the cell file explains (the arm in its measured configuration, the
  tool, a held part, fixtures and parts, each grown by the padding): never an obstacle.
- :mod:`.occupancy`: the map itself, log-odds per voxel (OctoMap's sensor model), hits
  where rays end, misses where they pass, in a direct-addressed table over the zone.
- :mod:`.path_check`: the rest of a trajectory checked against the map.

This is process protection (a tote, a misplaced part, a hand in a shared zone), never
personnel protection, which stays with the controller's safety system and safety-rated
sensors. Pure computation (numpy, scipy); the twin renders the images (:mod:`cellrunner.sim.depth`).
"""
