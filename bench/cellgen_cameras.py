"""Generated cells with cameras and markers (issue 33), registered into
``bench/cellgen.py``'s kinds: a feasible job of that generator given a camera, each
kind's ground truth what a correct ``check`` (and twin) must say.

- ``watched`` (feasible): a depth camera fixed high above the work looks straight down
  and feeds ``watch:``; its zone spans both tables and the air above them;
- ``camera_blind`` (broken): the same camera mounted with a half-turn roll slip, looking
  at the ceiling (SPEC section 12: the map would stay empty);
- ``aligned`` (feasible): a wrist camera and an ``align`` before the pick, on marker ID
  printed on the part's top face (``markers:``, SPEC section 13); in the twin the part
  lies a few millimetres and degrees off its frame, inside ``max_correction``;
- ``marker_off_part`` (broken): the align's inline marker written 20 mm above the part's
  top face (the twin would print it in the air and read the part 20 mm off);
- ``marker_too_small``  (broken): a 6 mm marker looked at from 300 mm (12 px wide): one
  look cannot hold the align's 0.5 deg tolerance.
"""

from __future__ import annotations

import random
from typing import Any

#: the feasible kinds and the defects this module adds, and the gripper they need
CAMERA_FEASIBLE = ("watched", "aligned")
CAMERA_DEFECTS = ("camera_blind", "marker_off_part", "marker_too_small")
CAMERA_KINDS = CAMERA_FEASIBLE + CAMERA_DEFECTS
ALIGN_KINDS = ("aligned", "marker_off_part", "marker_too_small")
NEEDS_JAWS = dict.fromkeys(ALIGN_KINDS, "jaws")

#: the wrist camera: on the flange beside the gripper, looking along the tool
WRIST = {
    "intrinsics": {"fx": 600, "fy": 600, "cx": 319.5, "cy": 239.5},
    "image_size": [640, 480],
    "mount": "flange",
    "pose": {"xyz": [0.07, 0, 0.05], "rpy": [0, 0, 0]},
}
#: the overhead depth camera's lens (px) and picture
OVERHEAD_F_PX, OVERHEAD_SIZE = 460, (640, 480)
#: how far the align looks from, and how far the part may lie off its frame
STANDOFF_M, OFF_M, OFF_DEG = 0.2, 0.005, 3.0
#: the align's max_correction: the part's offsets and what one look may misread them by
#: (0.3 mm and 0.4 deg, 2 std, docs/align.md), rounded up. check proves the centre and
#: corners of this box, so the witness must keep its margins for all of them
#: (:func:`align_witness_clear`); a box twice the offsets made the witness prove
#: corrections no job needs
MAX_CORRECTION_M, MAX_CORRECTION_DEG = 0.006, 4.0
#: samples along a correcting line at the look (it is 10 mm at most)
LOOK_LINE_SAMPLES = 11


def with_cameras(case: Any, seed: int) -> Any:
    """``case`` (a feasible job of ``bench/cellgen.py``, of kind one of CAMERA_KINDS)
    given its camera, and broken as its kind says."""
    rng = random.Random(seed * 7919 + 33)
    if case.kind in ("watched", "camera_blind"):
        _watch(case, blind=case.kind == "camera_blind")
    else:
        _align(case, rng)
    return case


def _watch(case: Any, blind: bool) -> None:
    """An overhead depth camera over both tables, its zone around them."""
    frames = case.cell["frames"]
    tables = [f for f in case.cell["fixtures"] if f["name"].endswith("_table")]
    xs = [f["pose"]["xyz"][0] for f in tables] + [frames[k]["xyz"][0] for k in frames]
    ys = [f["pose"]["xyz"][1] for f in tables] + [frames[k]["xyz"][1] for k in frames]
    low = min(f["pose"]["xyz"][2] for f in tables) - 0.05
    high = max(frames[k]["xyz"][2] for k in frames) + 0.25
    centre = [(min(xs) + max(xs)) / 2, (min(ys) + max(ys)) / 2, (low + high) / 2]
    size = [max(xs) - min(xs) + 0.5, max(ys) - min(ys) + 0.5, high - low]
    # high enough that the zone's top fills the picture's shorter side at most
    half_fov = min(OVERHEAD_SIZE) / 2 / OVERHEAD_F_PX
    above = max(size[0], size[1]) / 2 / half_fov
    camera_z = high + above
    roll = 0 if blind else 180  # the slip: half a turn about the camera's roll
    case.cell["cameras"] = {
        "overhead": {
            "intrinsics": {
                "fx": OVERHEAD_F_PX,
                "fy": OVERHEAD_F_PX,
                "cx": OVERHEAD_SIZE[0] / 2 - 0.5,
                "cy": OVERHEAD_SIZE[1] / 2 - 0.5,
            },
            "image_size": list(OVERHEAD_SIZE),
            "pose": {"xyz": [round(centre[0], 4), round(centre[1], 4), round(camera_z, 4)],
                     "rpy": [roll, 0, 90]},
            "depth": {"range": [0.3, round(camera_z - low + 1.0, 2)], "rate": 15},
        }
    }  # fmt: skip
    case.cell["watch"] = {
        "cameras": ["overhead"],
        "zone": {
            "box": {"size": [round(v, 4) for v in size]},
            "pose": {"xyz": [round(v, 4) for v in centre]},
        },
        "voxel": 0.02,
        "padding": 0.03,
    }


def _align(case: Any, rng: random.Random) -> None:
    """A wrist camera and an align on the part's marker before the pick."""
    part = case.cell["parts"][0]
    size = part["box"]["size"]
    edge = round(min(size[0], size[1]) - 0.006, 3)
    marker_id = case.seed % 50
    standoff = STANDOFF_M
    if case.kind == "marker_too_small":
        edge, standoff = 0.006, 0.3
    # beside the gripper, clear of its body and of the rail across the fingers' tops
    # that the twin draws (it reaches 10 mm and a finger past the open jaws)
    body_r = max(g["cylinder"]["radius"] for g in case.cell["tool"]["geometry"])
    stroke = case.cell["tool"]["gripper"]["stroke"]
    beside = round(max(body_r, stroke / 2 + 0.04) + 0.02, 3)
    case.cell["cameras"] = {
        "wrist": {**WRIST, "pose": {"xyz": [beside, 0, 0.05], "rpy": [0, 0, 0]}}
    }
    top = round(size[2] / 2, 4)
    part["offset"] = {
        "xyz": [round(rng.uniform(-OFF_M, OFF_M), 4), round(rng.uniform(-OFF_M, OFF_M), 4), 0],
        "rpy": [0, 0, round(rng.uniform(-OFF_DEG, OFF_DEG), 2)],
    }
    marker: Any
    if case.kind == "marker_off_part":
        # inline, in the infeed frame (its Z points down into the part): 20 mm above the top
        marker = {"dictionary": "DICT_4X4_50", "id": marker_id, "size": edge,
                  "pose": {"xyz": [0, 0, -round(top + 0.02, 4)], "rpy": [180, 0, 0]}}  # fmt: skip
    else:
        part["markers"] = [
            {"dictionary": "DICT_4X4_50", "id": marker_id, "size": edge,
             "pose": {"xyz": [0, 0, top]}}
        ]  # fmt: skip
        marker = marker_id
    align = {
        "camera": "wrist",
        "marker": marker,
        "tolerance": {"xyz": 0.001, "rpy": 0.5},
        "max_correction": {
            "xyz": [MAX_CORRECTION_M, MAX_CORRECTION_M, 0],
            "rpy": [0, 0, MAX_CORRECTION_DEG],
        },
        "attempts": 3,
        "standoff": standoff,
    }
    steps = case.task["steps"]
    at = next(i for i, s in enumerate(steps) if "pick" in s)
    steps.insert(at, {"align": align})


def align_witness_clear(case: Any, q_pick_rad: Any, approach_m: float, margin_m: float) -> bool:
    """The pick's witness of an align job keeps its margins for every correction check
    proves (the centre and corners of max_correction; the part lies up to OFF_M and
    OFF_DEG off in the twin, inside them): the corrected line down to the pick, tracked
    from the witness, and the look with the straight correcting line from it (the run
    time moves the camera with the correction before it looks again) stay
    ``margin_m`` over every clearance and off the singularities as every witness does
    (``bench.cellgen.keeps_margins``). Without the look and the corrections a UR10's look
    stood 6 deg off the wrist singularity and its correcting line went under the
    planner's 3 deg (s60019)."""
    import itertools
    import tempfile
    from pathlib import Path

    import numpy as np

    from bench.cellgen import _up, keeps_margins
    from cellrunner.model.geometry import pose_matrix
    from cellrunner.model.job_steps import job_steps
    from cellrunner.model.load import load_cell, load_task
    from cellrunner.planning.world import CellWorld

    with tempfile.TemporaryDirectory() as folder:
        cell_file, task_file = case.write(Path(folder))
        cell = load_cell(cell_file)
        steps = job_steps(load_task(task_file, cell), cell.cell, {})
    world = CellWorld(cell)
    kin, collision = world.kinematics, world.collision
    keep = np.array(["part" not in a and "part" not in b for a, b in collision.pair_labels])

    def clear(q: Any) -> bool:
        return keeps_margins(kin, collision, keep, q, margin_m)

    align = next(s for s in steps if s.kind == "align")
    look = next((s for s in steps if s.index == align.index - 1 and s.kind == "move"), None)
    F = align.extra["T_world_frame"]
    T_pick = kin.T_world_tcp(np.asarray(q_pick_rad, float))
    low, high = align.args.box()
    axes = [(a, b) if b > a else (a,) for a, b in zip(low, high, strict=True)]
    corners = [np.zeros(6), *(np.array(c) for c in itertools.product(*axes))]
    q_look = None
    if look is not None and look.T_world_tcp is not None:
        branches = [
            q for q in kin.ik_all(look.T_world_tcp, world.q_home_rad) if collision.is_valid(q)
        ]
        q_look = branches[0] if branches else None
        if q_look is None or not clear(q_look):
            return False
    for six in corners:

        def moved(share: float, six: Any = six) -> Any:
            C = pose_matrix(six[:3] * share, six[3:] * share)
            return F @ C @ np.linalg.inv(F)

        W = moved(1.0)
        q = kin.ik_track(W @ T_pick, np.asarray(q_pick_rad, float))  # the line down, up
        for k in range(int(approach_m / 0.005) + 1):
            q = None if q is None else kin.ik_track(W @ T_pick @ _up(k * 0.005), q)
            if not clear(q):
                return False
        if q_look is not None:  # the correcting line at the look
            assert look is not None
            q = q_look
            for share in np.linspace(0.0, 1.0, LOOK_LINE_SAMPLES):
                q = kin.ik_track(moved(float(share)) @ look.T_world_tcp, q)
                if not clear(q):
                    return False
    return True
