"""The gripper's shapes, as planning checks them and the twin builds them: a parallel
gripper's finger pads, or a vacuum gripper's cups; and the channels that drive it.

The jaws move along the TCP's X axis, symmetric about the TCP; each pad is a box
``FINGER_SIZE_M`` (thickness along X, width along Y, and along Z it spans ``PAD_Z_M``
around the TCP). Planning checks the pads where they are widest (fully open).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from cellrunner.model import geometry
from cellrunner.model.geometry import Box, Placed

if TYPE_CHECKING:
    from cellrunner.model.cell import Cup, Gripper

#: an IO channel and the value that acts on it
Channel = tuple[str, bool | float]

#: a Robotiq 2F gripper is driven through its own socket, not the robot's IO; the engine
#: and the backends address it through these two virtual channels
ROBOTIQ_CLOSE = "RQ0"  # output: true closes the jaws (SET POS 255), false opens them
ROBOTIQ_OBJECT = "RQ_OBJ"  # input: true when the gripper reports an object detected (OBJ 2)

FINGER_SIZE_M = (0.012, 0.022, 0.045)  # thickness (X), width (Y), length (Z)
PAD_Z_M = (-0.02, 0.02)  # pad extent along the TCP's Z, around the TCP
#: the two pads' names (+X, -X)
JAW_PADS = ("jaw_a", "jaw_b")


def open_pads(stroke_m: float, T_flange_tcp: np.ndarray) -> list[Placed]:
    """Both pads fully open, placed in the flange frame."""
    t, w, _ = FINGER_SIZE_M
    z0, z1 = PAD_Z_M
    pads = []
    for name, sign in zip(JAW_PADS, (1.0, -1.0), strict=True):
        x = sign * (stroke_m / 2 + t / 2)
        pads.append(
            Placed(
                name,
                Box((t, w, z1 - z0)),
                T_flange_tcp @ geometry.pose_matrix((x, 0.0, (z0 + z1) / 2)),
            )
        )
    return pads


#: the jaws' frame as the twin draws it (what a wrist camera sees of it, and so what
#: check's line-of-sight test takes as in the way): a rail across the fingers' tops
#: ``RAIL_ABOVE_M`` above the pads (its centre), ``RAIL_HALF_Z_M`` half thick, reaching
#: ``RAIL_MARGIN_M`` (x, y) past the open fingers; and each finger's stem, from the pad's
#: top ``2 * STEM_HALF_Z_M`` up
RAIL_ABOVE_M, RAIL_HALF_Z_M, RAIL_MARGIN_M = 0.02, 0.008, (0.01, 0.004)
STEM_HALF_Z_M = 0.012


def jaw_frame(
    stroke_m: float,
    finger_size_m: tuple[float, float, float] = FINGER_SIZE_M,
    pad_z_m: tuple[float, float] = PAD_Z_M,
) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """The rail and the two stems of open jaws, each as (name, centre, full size) in the
    TCP frame (m): the geometry the twin draws above the pads (not in contact: a wrist
    camera sees it)."""
    t, w, _ = finger_size_m
    z0 = pad_z_m[0]
    half = stroke_m / 2
    rail = np.array(
        [2 * (half + t + RAIL_MARGIN_M[0]), w + 2 * RAIL_MARGIN_M[1], 2 * RAIL_HALF_Z_M]
    )
    out = [("rail", np.array([0.0, 0.0, z0 - RAIL_ABOVE_M]), rail)]
    for name, sign in zip(JAW_PADS, (1.0, -1.0), strict=True):
        centre = np.array([sign * (half + t / 2), 0.0, z0 - STEM_HALF_Z_M])
        out.append((f"stem:{name}", centre, np.array([t, w, 2 * STEM_HALF_Z_M])))
    return out


def jaw_frame_shapes(gripper: Gripper | None, T_flange_tcp: np.ndarray) -> list[Placed]:
    """:func:`jaw_frame` of a parallel gripper, open, as boxes in the flange frame (none
    for cups)."""
    if gripper is None or gripper.kind == "vacuum":
        return []
    return [
        Placed(
            name,
            Box((float(size[0]), float(size[1]), float(size[2]))),
            T_flange_tcp @ geometry.pose_matrix(c),
        )
        for name, c, size in jaw_frame(float(gripper.stroke))
    ]


#: a suction cup's body: its face is at the cup's xyz, its body this long above it (m)
CUP_LENGTH_M = 0.02


def cup_shapes(cups: Sequence[Cup], T_flange_tcp: np.ndarray) -> list[Placed]:
    """Each cup as a cylinder in the flange frame, its face at the cup's point (TCP frame)
    and its body reaching back along the TCP's -Z."""
    from cellrunner.model.geometry import Cylinder

    return [
        Placed(
            f"cup{i}",
            Cylinder(float(c.radius), CUP_LENGTH_M),
            T_flange_tcp @ geometry.pose_matrix((c.xyz[0], c.xyz[1], c.xyz[2] - CUP_LENGTH_M / 2)),
        )
        for i, c in enumerate(cups)
    ]


def gripper_shapes(gripper: Gripper | None, T_flange_tcp: np.ndarray) -> list[Placed]:
    """What planning checks of the gripper: the cups of a vacuum gripper (no fingers),
    else the finger pads fully open."""
    if gripper is None:
        return []
    if gripper.kind == "vacuum":
        return cup_shapes(gripper.cups, T_flange_tcp)
    return open_pads(gripper.stroke, T_flange_tcp)


def part_center_depth_m(gripper: Gripper | None, shape: geometry.Shape | None) -> float:
    """How far below its frame (along the frame's Z, into the part) a part's centre lies:
    a suction gripper holds a part by its top face, under the cups' faces (at the frame when
    the cups sit at the TCP), jaws by its middle."""
    if gripper is None or gripper.kind != "vacuum":
        return 0.0
    from cellrunner.model.geometry import Box, Cylinder, Sphere

    cups_z = max((float(c.xyz[2]) for c in gripper.cups), default=0.0)
    if isinstance(shape, Box):
        return cups_z + float(shape.size_m[2]) / 2
    if isinstance(shape, Cylinder):
        return cups_z + float(shape.length_m) / 2
    if isinstance(shape, Sphere):
        return cups_z + float(shape.radius_m)
    return cups_z


def width_across_jaws_m(shape: geometry.Shape, T_tcp_shape: np.ndarray) -> float | None:
    """The part's extent along the TCP's X axis, the axis the jaws close along (m), for a
    part placed at ``T_tcp_shape`` in the TCP frame; None for a mesh (not measured)."""
    from cellrunner.model.geometry import Cylinder, Sphere

    axes = np.asarray(T_tcp_shape, float)[:3, :3]  # the shape's axes in the TCP frame
    x_in_shape = axes[0]  # the TCP's X in the shape's axes
    if isinstance(shape, Box):
        return float(np.abs(x_in_shape) @ np.asarray(shape.size_m, float))
    if isinstance(shape, Cylinder):
        along = abs(float(x_in_shape[2]))
        across = float(np.sqrt(max(0.0, 1.0 - along * along)))
        return float(along * shape.length_m + across * 2.0 * shape.radius_m)
    if isinstance(shape, Sphere):
        return 2.0 * float(shape.radius_m)
    return None


def gripper_channels(
    gripper: Gripper | None, outputs: dict[str, str], inputs: dict[str, str]
) -> tuple[Channel | None, Channel | None, str | None]:
    """(close channel and value, open channel and value or None, closed-sensor channel) of
    the cell's gripper: IO channels for ``kind: io``, the virtual Robotiq channels for
    ``kind: robotiq`` (where the cell names no IO of its own)."""
    if gripper is None:
        return None, None, None
    if gripper.kind == "vacuum":  # suction on "closes", the vacuum switch confirms
        close = (
            (outputs[gripper.suction.output], gripper.suction.value) if gripper.suction else None
        )
        return close, None, inputs[gripper.vacuum_ok] if gripper.vacuum_ok else None
    if gripper.kind == "robotiq" and gripper.close is None:
        sensor: str | None = (
            inputs[gripper.closed_sensor] if gripper.closed_sensor else ROBOTIQ_OBJECT
        )
        return (ROBOTIQ_CLOSE, True), None, sensor
    close = (outputs[gripper.close.output], gripper.close.value) if gripper.close else None
    open_ = (outputs[gripper.open.output], gripper.open.value) if gripper.open else None
    sensor = inputs[gripper.closed_sensor] if gripper.closed_sensor else None
    return close, open_, sensor
