"""Cluttered scenes for the planning benchmark: for a UR5e a table with a wall and clutter,
a shelf, two bins; for the large arms a UR20 palletizing cell, a UR30 tending a machine
through its door and a UR15 at a tall rack. The robot base is the world frame (z = 0 on
its table or pedestal). Each problem is a pair of TCP poses (tool pointing down, or into
the shelf or machine), solved by IK on the branch nearest a reference configuration."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from cellrunner.model.geometry import Box, Cylinder, Placed, pose_matrix

HOME_DEG = (180.0, -90.0, 90.0, -90.0, -90.0, 0.0)  # facing +x, the work side
DOWN = (180.0, 0.0, 0.0)  # tool z pointing down
FORWARD = (0.0, 90.0, 0.0)  # tool z pointing along world +x


@dataclass(frozen=True)
class Scene:
    name: str
    fixtures: tuple[Placed, ...]
    targets: tuple[tuple[str, np.ndarray], ...]  # named T_world_tcp poses
    problems: tuple[tuple[str, str], ...]  # (start target, goal target)
    model: str = "ur5e"  # the arm (cellrunner.model.robots)


def box(name: str, size, xyz, rpy=(0.0, 0.0, 0.0)) -> Placed:
    return Placed(name, Box(tuple(float(s) for s in size)), pose_matrix(xyz, rpy))


def tool() -> tuple[Placed, ...]:
    """A parallel gripper: a body cylinder and two fingers, in the flange frame."""
    return (
        Placed("body", Cylinder(0.04, 0.10), pose_matrix((0, 0, 0.05))),
        box("finger_a", (0.015, 0.02, 0.05), (0.025, 0, 0.125)),
        box("finger_b", (0.015, 0.02, 0.05), (-0.025, 0, 0.125)),
    )


T_FLANGE_TCP = pose_matrix((0, 0, 0.15))


def table_scene() -> Scene:
    fixtures = (
        box("table", (1.6, 1.6, 0.04), (0.0, 0.0, -0.02)),
        box("wall", (0.4, 0.03, 0.30), (0.50, 0.0, 0.15)),
        box("crate", (0.16, 0.16, 0.22), (0.25, -0.45, 0.11)),
        box("feeder", (0.12, 0.30, 0.30), (0.70, -0.25, 0.15)),
        box("post_a", (0.06, 0.06, 0.55), (-0.35, 0.35, 0.275)),
        box("post_b", (0.06, 0.06, 0.55), (-0.35, -0.35, 0.275)),
        box("tray", (0.25, 0.18, 0.06), (0.30, 0.45, 0.03)),
        box("gantry", (0.04, 0.9, 0.04), (0.60, 0.0, 0.75)),
    )
    targets = (
        ("pick_a", pose_matrix((0.45, -0.25, 0.06), DOWN)),
        ("pick_b", pose_matrix((0.55, -0.30, 0.40), DOWN)),
        ("place_a", pose_matrix((0.45, 0.25, 0.06), DOWN)),
        ("place_b", pose_matrix((0.30, 0.45, 0.14), DOWN)),
        ("back_a", pose_matrix((-0.40, 0.0, 0.20), DOWN)),
        ("side_a", pose_matrix((0.10, -0.55, 0.30), DOWN)),
    )
    problems = (
        ("pick_a", "place_a"),
        ("place_a", "pick_a"),
        ("pick_b", "place_b"),
        ("place_b", "pick_a"),
        ("back_a", "place_a"),
        ("pick_a", "back_a"),
        ("side_a", "place_b"),
        ("place_a", "side_a"),
    )
    return Scene("table", fixtures, targets, problems)


def shelf_scene() -> Scene:
    x0, depth, width = 0.50, 0.30, 0.80
    fixtures = [box("table", (1.6, 1.6, 0.04), (0.0, 0.0, -0.02))]
    fixtures.append(box("shelf_back", (0.02, width, 0.95), (x0 + depth, 0.0, 0.475)))
    for side, y in (("left", width / 2), ("right", -width / 2)):
        fixtures.append(box(f"shelf_{side}", (depth, 0.02, 0.95), (x0 + depth / 2, y, 0.475)))
    for k, z in enumerate((0.25, 0.55, 0.85)):
        fixtures.append(box(f"board_{k}", (depth, width, 0.02), (x0 + depth / 2, 0.0, z)))
    fixtures.append(box("divider", (depth, 0.02, 0.30), (x0 + depth / 2, 0.0, 0.40)))
    targets = (
        ("low_left", pose_matrix((0.58, 0.20, 0.12), FORWARD)),
        ("low_right", pose_matrix((0.58, -0.20, 0.12), FORWARD)),
        ("mid_left", pose_matrix((0.58, 0.20, 0.40), FORWARD)),
        ("mid_right", pose_matrix((0.58, -0.20, 0.40), FORWARD)),
        ("top_centre", pose_matrix((0.56, 0.0, 0.70), FORWARD)),
    )
    problems = (
        ("low_left", "mid_left"),
        ("mid_left", "mid_right"),
        ("mid_right", "low_right"),
        ("low_right", "top_centre"),
        ("top_centre", "low_left"),
        ("mid_right", "mid_left"),
    )
    return Scene("shelf", tuple(fixtures), targets, problems)


def bin_scene() -> Scene:
    fixtures = [box("table", (1.6, 1.6, 0.04), (0.0, 0.0, -0.02))]
    wall_h, size, t = 0.16, 0.30, 0.02
    bins = {"bin_a": (0.40, -0.35), "bin_b": (0.40, 0.35), "bin_c": (-0.05, 0.50)}
    for name, (cx, cy) in bins.items():
        for side, (dx, dy, sx, sy) in {
            "n": (0, size / 2, size, t),
            "s": (0, -size / 2, size, t),
            "e": (size / 2, 0, t, size),
            "w": (-size / 2, 0, t, size),
        }.items():
            fixtures.append(box(f"{name}_{side}", (sx, sy, wall_h), (cx + dx, cy + dy, wall_h / 2)))
    fixtures.append(box("chute", (0.10, 0.10, 0.45), (0.50, 0.0, 0.225)))
    targets = (
        ("a_corner", pose_matrix((0.45, -0.40, 0.05), DOWN)),
        ("a_centre", pose_matrix((0.38, -0.33, 0.05), (180, 0, 45))),
        ("b_corner", pose_matrix((0.45, 0.40, 0.05), DOWN)),
        ("b_centre", pose_matrix((0.37, 0.33, 0.05), (180, 0, -30))),
        ("c_centre", pose_matrix((-0.05, 0.50, 0.06), DOWN)),
    )
    problems = (
        ("a_corner", "b_corner"),
        ("b_centre", "a_centre"),
        ("a_centre", "c_centre"),
        ("c_centre", "a_corner"),
        ("b_corner", "c_centre"),
        ("a_corner", "b_centre"),
    )
    return Scene("bin", tuple(fixtures), targets, problems)


def palletizing_scene_ur20() -> Scene:
    """A UR20 on a 0.3 m pedestal: infeed conveyor on its right, a pallet half stacked
    (two layers of cases) in front, fences behind and on the left."""
    fixtures = (
        box("floor", (4.0, 4.0, 0.04), (0.0, 0.0, -0.32)),
        box("pedestal", (0.40, 0.40, 0.30), (0.0, 0.0, -0.15)),
        box("conveyor", (0.50, 1.60, 0.75), (0.40, -1.10, 0.075)),
        box("pallet", (0.80, 1.20, 0.144), (0.95, 0.35, -0.228)),
        box("stack", (0.62, 0.82, 0.44), (0.86, 0.16, 0.064)),
        box("fence_back", (0.05, 3.4, 2.0), (-0.70, 0.0, 0.70)),
        box("fence_side", (2.3, 0.05, 2.0), (0.45, 1.25, 0.70)),
    )
    targets = (
        ("infeed", pose_matrix((0.40, -0.80, 0.62), DOWN)),
        ("stack_top_near", pose_matrix((0.70, 0.0, 0.52), DOWN)),
        ("stack_top_far", pose_matrix((1.05, 0.40, 0.52), DOWN)),
        ("pallet_free", pose_matrix((0.85, 0.78, 0.08), (180, 0, 90))),
        ("pallet_free_far", pose_matrix((1.15, 0.78, 0.08), (180, 0, 90))),
    )
    problems = (
        ("infeed", "stack_top_near"),
        ("stack_top_far", "infeed"),
        ("infeed", "pallet_free"),
        ("pallet_free_far", "infeed"),
        ("stack_top_near", "pallet_free_far"),
    )
    return Scene("ur20_pallet", fixtures, targets, problems, model="ur20")


def machine_scene_ur30() -> Scene:
    """A UR30 beside a machine tool: the part goes from a raw-parts table through the
    machine's door opening (0.5 m x 0.5 m) onto the vise, and out to a finished table."""
    x0, t = 0.85, 0.03
    fixtures = (
        box("floor", (4.0, 4.0, 0.04), (0.0, 0.0, -0.72)),
        box("raw_table", (0.6, 0.5, 0.04), (0.25, -0.75, -0.02)),
        box("done_table", (0.6, 0.5, 0.04), (0.25, 0.75, -0.02)),
        box("door_left", (t, 0.35, 1.2), (x0, 0.425, 0.20)),
        box("door_right", (t, 0.35, 1.2), (x0, -0.425, 0.20)),
        box("door_sill", (t, 0.5, 0.50), (x0, 0.0, -0.15)),
        box("door_lintel", (t, 0.5, 0.20), (x0, 0.0, 0.70)),
        box("machine_roof", (0.70, 1.2, t), (x0 + 0.35, 0.0, 0.80)),
        box("machine_back", (t, 1.2, 1.2), (x0 + 0.70, 0.0, 0.20)),
        box("vise", (0.20, 0.16, 0.20), (x0 + 0.38, 0.0, 0.0)),
    )
    targets = (
        ("raw", pose_matrix((0.25, -0.75, 0.08), DOWN)),
        ("done", pose_matrix((0.25, 0.75, 0.08), DOWN)),
        ("vise_top", pose_matrix((x0 + 0.38, 0.0, 0.16), DOWN)),
        ("at_door", pose_matrix((x0 - 0.12, 0.0, 0.35), FORWARD)),
        ("vise_front", pose_matrix((x0 + 0.20, 0.0, 0.32), FORWARD)),
    )
    problems = (
        ("raw", "vise_top"),
        ("vise_top", "done"),
        ("done", "raw"),
        ("at_door", "vise_front"),
        ("vise_front", "raw"),
    )
    return Scene("ur30_machine", fixtures, targets, problems, model="ur30")


def rack_scene(model: str) -> Scene:
    """An arm of about 1.3 m reach (the UR15, the CB3 UR10) on a 0.6 m pedestal in front of
    a four-level rack, 1.1 m wide."""
    x0, depth, width = 0.70, 0.35, 1.10
    fixtures = [
        box("floor", (4.0, 4.0, 0.04), (0.0, 0.0, -0.62)),
        box("pedestal", (0.30, 0.30, 0.60), (0.0, 0.0, -0.30)),
        box("rack_back", (0.02, width, 1.60), (x0 + depth, 0.0, 0.20)),
    ]
    for side, y in (("left", width / 2), ("right", -width / 2)):
        fixtures.append(box(f"rack_{side}", (depth, 0.02, 1.60), (x0 + depth / 2, y, 0.20)))
    for k, z in enumerate((-0.40, -0.05, 0.30, 0.65, 1.00)):
        fixtures.append(box(f"board_{k}", (depth, width, 0.02), (x0 + depth / 2, 0.0, z)))
    fixtures.append(box("divider", (depth, 0.02, 0.70), (x0 + depth / 2, 0.0, 0.30)))
    targets = (
        ("low_left", pose_matrix((0.80, 0.30, -0.30), FORWARD)),
        ("mid_right", pose_matrix((0.80, -0.30, 0.05), FORWARD)),
        ("mid_left", pose_matrix((0.80, 0.30, 0.40), FORWARD)),
        ("high_right", pose_matrix((0.78, -0.30, 0.75), FORWARD)),
        ("floor_tote", pose_matrix((0.10, -0.70, -0.40), DOWN)),
    )
    problems = (
        ("low_left", "high_right"),
        ("mid_right", "mid_left"),
        ("high_right", "low_left"),
        ("floor_tote", "mid_left"),
        ("mid_right", "floor_tote"),
    )
    return Scene(f"{model}_rack", tuple(fixtures), targets, problems, model=model)


def scenes() -> tuple[Scene, ...]:
    return (table_scene(), shelf_scene(), bin_scene())


def large_arm_scenes() -> tuple[Scene, ...]:
    """Scenes for the other arms, reported apart from the UR5e headline: the UR20, UR30 and
    UR15 (no collision geometry: reported as not planned), and the CB3 arms our users
    started from (the UR5 at the UR5e's shelf, the UR10 at the rack)."""
    return (
        palletizing_scene_ur20(),
        machine_scene_ur30(),
        rack_scene("ur15"),
        replace(shelf_scene(), name="ur5_shelf", model="ur5"),
        rack_scene("ur10"),
    )
