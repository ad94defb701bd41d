"""How sure one look at an ArUco marker is: the spread of the pose a camera reads,
predicted from the marker's size, the standoff and the focal length (a pinhole model
of corner noise).

Each of the marker's four corners is found with an independent error of
``CORNER_NOISE_PX`` (std, px, each image axis; a sharp 8-bit picture and sub-pixel
corner refinement). The marker spans ``a = f s / Z`` px (focal length ``f`` px, edge
``s`` m, standoff ``Z`` m). One look's std, to first order:

- across the line of sight (x, y): ``sigma Z / (2 f)`` (the mean of four corners);
- the turn about the line of sight (rz): ``sigma / (a sqrt(2))`` rad read in the
  marker's plane (a rigid fit of four corners at ``a / sqrt(2)`` px from the centre),
  ``sigma / a`` from the full pose;
- along the line of sight (z): ``sigma Z / (1.2 a)`` (the marker's apparent size);
- the tilts (rx, ry): ``sqrt(1.6 sigma / a)`` rad. A marker seen face on shows a small
  tilt only as foreshortening, ``a (1 - cos tilt) ~ a tilt^2 / 2``, so the tilt's error
  falls with the square root of the marker's span, not its span; the 1.6 is fitted to
  OpenCV's IPPE solver on markers 24-200 px wide
  (``tests/planning/test_camera_proofs.py`` holds the model to it);
- a rotation error moves the frame the marker is given in by that angle times the
  marker's distance from the frame's origin (its lever).

A look that reads only x, y and rz (``max_correction`` z, rx and ry 0: the marker lies
in its known plane and the rays of its corners are cut with it) has the first two; the
full pose has them all. For a 30 mm marker at 375 mm through a 600 px lens (the
default look: it spans 48 px, 10 % of a 480 px picture) the tilts' std is 5 deg, the
planar reading's 0.08 mm and 0.2 deg. A step keeps a tolerance ``ALIGN_SIGMAS`` times the
predicted std (about 19 looks in 20 read within it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: std of one corner's position in the picture (px, each axis)
CORNER_NOISE_PX = 0.25
#: the constants of the full pose's depth and tilts, fitted to OpenCV's IPPE solver
TILT_FIT, TILT_FIT_SIZE = 1.6, 1.2
#: a tolerance must hold this many predicted std of a look
ALIGN_SIGMAS = 2.0


@dataclass(frozen=True)
class LookNoise:
    """One look's predicted std: of the frame's position (m, the norm over its axes,
    the rotation's lever included) and of its rotation (rad, the norm over its axes)."""

    position_m: float
    rotation_rad: float
    span_px: float

    def within(self, tolerance_m: float, tolerance_rad: float) -> bool:
        return (
            ALIGN_SIGMAS * self.position_m <= tolerance_m
            and ALIGN_SIGMAS * self.rotation_rad <= tolerance_rad
        )


def look_noise(
    size_m: float, standoff_m: float, focal_px: float, lever_m: float, full_pose: bool
) -> LookNoise:
    """The std of one look at a marker of edge ``size_m`` from ``standoff_m`` through a
    lens of ``focal_px``, read as a frame ``lever_m`` from the marker's centre;
    ``full_pose``: all six axes are read, else x, y and rz."""
    sigma, z, f, s = CORNER_NOISE_PX, standoff_m, focal_px, size_m
    a = f * s / z
    across = sigma * z / (2 * f)
    position2 = 2 * across**2
    rotation2 = (sigma / (a * math.sqrt(2))) ** 2
    if full_pose:
        along = sigma * z / (TILT_FIT_SIZE * a)
        tilt = math.sqrt(TILT_FIT * sigma / a)
        position2 += along**2
        rotation2 = (sigma / a) ** 2 + 2 * tilt**2
    position2 += rotation2 * lever_m**2
    return LookNoise(math.sqrt(position2), math.sqrt(rotation2), a)
