"""Generated hole cells (issue 33): a pin picked from a table and inserted into a hole.

The hole is a block on the outfeed table modelled as the cell file allows: four walls
(boxes ``wall_xm``, ``wall_xp``, ``wall_ym``, ``wall_yp``) around a square hole, and its
floor (``hole_floor``) under it, turned with the pin. The pin is a square bar standing on
its end, held by jaws at its centre (flat faces on the pads: a round pin between flat
pads pivots about the jaws' axis as the arm carries it, 1.5 deg puts its tip 1.2 mm
off, and a UR10e's carry did); the frame ``hole`` is where the TCP stands when the pin's tip is at the
hole's mouth (as in SPEC section 12). The job: ``move home -> pick -> approach the hole
-> descend to its mouth -> insert (contact: the walls) -> release -> retreat -> home``.

The place witness is a joint configuration over the hole (``bench/cellgen.py``'s
witnesses), so the job is reachable by construction; the kinds set the fit:

- ``hole_fit`` (feasible): the pin's faces 0.25-3 mm from the walls, the floor 2.5-4 mm
  below the insert's end (it keeps the cell's clearance: it is not in ``contact:``);
- ``hole_too_shallow``: the floor 6-12 mm above the insert's end (a hole 8 mm deep for
  an insert of 20): the pin meets a fixture not in ``contact:`` before ``expect_depth``,
  the insert stops there and fails (3);
- ``jam_rim``: the frame 0.7 mm over the rim of ``wall_xp`` (no chamfer): the pin's tip
  lands on the wall's top face and jams;
- ``jam_interference``: the hole 0.1 mm narrower than the pin on each face and no
  ``force: {min}`` (not a press fit the cell file declares): the pin jams.

And the press fits the insert declares (``force: {min, max}``, drawn after the others so
the kinds above keep their draws):

- ``press_fit`` (feasible): the hole 0.02-0.1 mm narrower than the pin on each face (0.1
  mm or more under the 0.2 mm a press fit may overlap a face, as the witnesses keep their
  clearances by a margin), a window of 10-40 N up to 30-100 N: the pin presses in, its
  force builds up;
- ``press_fit_loose``: the same window on a hole with clearance (as ``hole_fit``): the
  force never builds up, the press fit is not made (3);
- ``press_fit_jam``: the hole 0.4-0.6 mm narrower on each face, more than a press fit
  gives (0.2 mm, and the twin's 0.1 mm for the pin's placement): the pin jams.

The four kinds above are drawn again with chamfered walls (``KIND_chamfered``,
:mod:`bench.cellgen_chamfers`): the same seed's case with every wall a convex mesh, its top
inner edge bevelled 1-3 mm at 45 deg. The truth stays the plain kind's, as a UR holds a
part in position control (its force mode is compliant along the insert's axis only, so a
chamfer steers nothing sideways): a centred pin with clearance goes in past the chamfers
without touching them (feasible); a pin whose tip lands on a chamfer's slope or on the
rim past it jams just as on a rim without a chamfer; a hole too shallow and an
interference fit stay broken (the chamfers lead the pin onto the interference).
"""

from __future__ import annotations

import random
from typing import Any

import numpy as np

#: the feasible hole kinds and the broken ones (each breaks one thing)
HOLE_FEASIBLE = ("hole_fit",)
HOLE_DEFECTS = ("hole_too_shallow", "jam_rim", "jam_interference")
#: the declared press fits (added after the kinds above; sampled on seeds of their own)
PRESS_FEASIBLE = ("press_fit",)
PRESS_DEFECTS = ("press_fit_loose", "press_fit_jam")
PRESS_KINDS = PRESS_FEASIBLE + PRESS_DEFECTS
HOLE_KINDS = HOLE_FEASIBLE + HOLE_DEFECTS + PRESS_KINDS
#: how far the pin's tip is over the rim of wall_xp in a jam_rim case (m)
RIM_OVERLAP_M = 0.0007
#: the interference of a jam_interference case, per face (m, negative: overlap)
INTERFERENCE_M = -0.0001
#: the interference per face of a press_fit (m, negative: overlap) and of a press_fit_jam
PRESS_FIT_M = (-0.0001, -0.00002)
PRESS_JAM_M = (-0.0006, -0.0004)
WALLS = ("wall_xm", "wall_xp", "wall_ym", "wall_yp")
WALL_THICKNESS_M = 0.02
#: the hole block's walls stand this tall on the outfeed table (m)
WALL_HEIGHT_M = 0.04
APPROACH_ABOVE_M = 0.03


def generate(seed: int, kind: str) -> Any:
    """The hole case of ``seed`` as ``kind`` says (one of :data:`HOLE_KINDS`)."""
    from bench import cellgen

    if kind not in HOLE_KINDS:
        raise ValueError(f"unknown hole kind {kind!r}; known: {', '.join(HOLE_KINDS)}")
    rng = random.Random(seed)
    for _ in range(cellgen.WITNESS_TRIES):
        draw = _draw(rng, kind)
        case = _case(seed, kind, draw)
        if _witness_clear(case, draw):
            return case
    raise RuntimeError(f"seed {seed}: no hole witnesses clear")


def _draw(rng: random.Random, kind: str) -> dict[str, Any]:
    """The arm, the pin, the fit and the two witnesses of one hole job."""
    from bench import cellgen
    from cellrunner.model.robots import robot_spec

    model = rng.choice(cellgen.ARMS)
    mount = "ceiling" if rng.random() < cellgen.CEILING_SHARE else "floor"
    reach_m = robot_spec(model).reach_m
    tcp_m = round(rng.uniform(0.12, 0.18), 3)
    kin = cellgen._kinematics(model, tcp_m, mount)
    radius = round(rng.uniform(0.005, 0.01), 4)
    # the jaws' pads reach 20 mm below the TCP (the pin's centre): a pin long enough that
    # they stay 5 mm or more above the walls at the insert's end
    length = round(rng.uniform(0.09, 0.10), 3)
    depth = round(rng.uniform(0.015, length / 2 - 0.025), 4)
    clearance = round(rng.uniform(0.00025, 0.003), 5)
    if kind == "jam_interference":
        clearance = INTERFERENCE_M
    # the floor under the insert's end (m): beyond the cell's clearance (2 mm and 0.1 mm
    # of proof tolerance), which it keeps, as it is not named in contact:
    floor_below = round(rng.uniform(0.0025, 0.004), 4)
    if kind == "hole_too_shallow":
        floor_below = -round(rng.uniform(0.006, 0.012), 4)
    drawn = {
        "model": model,
        "mount": mount,
        "tcp_m": tcp_m,
        "kin": kin,
        "radius": radius,
        "length": length,
        "depth": depth,
        "clearance": clearance,
        "floor_below": floor_below,
        "mass": round(rng.uniform(0.05, 0.2), 3),
        "stroke": round(2 * radius + rng.uniform(0.02, 0.04), 3),
        "force_N": round(rng.uniform(15, 30), 1),
        "q_pick": cellgen._witness(rng, kin, rng.uniform(-150, -40), reach_m, mount),
        "q_place": cellgen._witness(rng, kin, rng.uniform(40, 150), reach_m, mount),
    }
    if kind in PRESS_KINDS:  # drawn last: the other kinds keep their draws
        if kind == "press_fit":
            drawn["clearance"] = round(rng.uniform(*PRESS_FIT_M), 6)
        elif kind == "press_fit_jam":
            drawn["clearance"] = round(rng.uniform(*PRESS_JAM_M), 6)
        low = round(rng.uniform(10, 40), 1)
        drawn["press_N"] = (low, round(low + rng.uniform(20, 60), 1))
    return drawn


def _case(seed: int, kind: str, d: dict[str, Any]) -> Any:
    """The files of draw ``d``: cellgen's pick-and-place cell with the outfeed table's
    part turned into a hole block and the place into an insert."""
    from bench import cellgen

    kin = d["kin"]
    T_pick, T_hole = kin.T_world_tcp(d["q_pick"]), kin.T_world_tcp(d["q_place"])
    half = d["length"] / 2
    mouth_z = float(T_hole[2, 3]) - half
    table_top = mouth_z - WALL_HEIGHT_M
    cx, cy = float(T_hole[0, 3]), float(T_hole[1, 3])
    frame = T_hole.copy()
    # the hole's axes: the pin's (the TCP's X, across the jaws, and the horizontal normal)
    ux = [float(v) for v in T_hole[:3, 0] / float(np.linalg.norm(T_hole[:3, 0]))]
    uy = [-ux[1], ux[0], 0.0]
    yaw_deg = round(float(np.degrees(np.arctan2(ux[1], ux[0]))), 4)
    if kind == "jam_rim":  # the pin's tip over the rim of wall_xp by RIM_OVERLAP_M
        frame[:3, 3] += (d["clearance"] + RIM_OVERLAP_M) * np.asarray(ux)
    w = 2 * (d["radius"] + d["clearance"])  # the hole's side
    t = WALL_THICKNESS_M
    z = round(mouth_z - WALL_HEIGHT_M / 2, 5)
    walls = [
        ("wall_xm", (-w / 2 - t / 2, 0.0), (t, w + 2 * t)),
        ("wall_xp", (w / 2 + t / 2, 0.0), (t, w + 2 * t)),
        ("wall_ym", (0.0, -w / 2 - t / 2), (w, t)),
        ("wall_yp", (0.0, w / 2 + t / 2), (w, t)),
    ]
    fixtures = [
        {
            "name": name,
            "box": {"size": [round(sx, 5), round(sy, 5), WALL_HEIGHT_M]},
            "pose": {
                "xyz": [
                    round(cx + a * ux[0] + b * uy[0], 5),
                    round(cy + a * ux[1] + b * uy[1], 5),
                    z,
                ],
                "rpy": [0, 0, yaw_deg],
            },
        }
        for name, (a, b), (sx, sy) in walls
    ]
    floor_top = mouth_z - d["depth"] - d["floor_below"]
    floor_h = floor_top - table_top
    fixtures.append(
        {
            "name": "hole_floor",
            "box": {"size": [round(w, 5), round(w, 5), round(floor_h, 5)]},
            "pose": {
                "xyz": [round(cx, 5), round(cy, 5), round(table_top + floor_h / 2, 5)],
                "rpy": [0, 0, yaw_deg],
            },
        }
    )
    tcp_m = d["tcp_m"]
    body_m = round(tcp_m - 0.06, 3)
    cell = {
        "cell": f"gen-{seed}-{kind}",
        "robot": {
            "model": d["model"],
            "host": "127.0.0.2",
            "backend": "sim",
            "mount": {
                "xyz": list(cellgen.MOUNTS[d["mount"]][0]),
                "rpy": list(cellgen.MOUNTS[d["mount"]][1]),
            },
            "home": list(cellgen.HOME_DEG),
        },
        "tool": {
            "tcp": {"xyz": [0, 0, tcp_m], "rpy": [0, 0, 0]},
            "payload": {"mass": 1.0, "cog": [0, 0, round(tcp_m / 3, 3)]},
            "gripper": {
                "kind": "io",
                "close": {"output": "gripper_close", "value": True},
                "closed_sensor": "gripper_closed",
                "stroke": d["stroke"],
            },
            "geometry": [
                {
                    "cylinder": {
                        "radius": round(max(0.03, d["stroke"] / 2 + 0.015), 3),
                        "length": body_m,
                    },
                    "xyz": [0, 0, round(body_m / 2, 4)],
                }
            ],
        },
        "io": {"outputs": {"gripper_close": "DO0"}, "inputs": {"gripper_closed": "DI0"}},
        "fixtures": [
            cellgen._base_fixture(d["mount"]),
            cellgen._table("infeed_table", T_pick, float(T_pick[2, 3]) - half),
            cellgen._table("outfeed_table", T_hole, table_top),
            *fixtures,
        ],
        "frames": {
            "infeed": {"xyz": cellgen._xyz(T_pick), "rpy": cellgen._rpy_deg(T_pick)},
            "hole": {"xyz": cellgen._xyz(frame), "rpy": cellgen._rpy_deg(frame)},
        },
        "parts": [
            {
                "name": "pin",
                "box": {
                    "size": [round(2 * d["radius"], 5), round(2 * d["radius"], 5), d["length"]]
                },
                "mass": d["mass"],
                "at": "infeed",
            }
        ],
        "tasks": {1: "task.yaml"},
        "journal": "var/jobs.sqlite",
    }
    depth = d["depth"]
    insert = {
        "to": "hole",
        "depth": depth,
        "speed": 0.01,
        "force": (
            {"min": d["press_N"][0], "max": d["press_N"][1]}
            if "press_N" in d
            else {"max": d["force_N"]}
        ),
        "expect_depth": [round(depth - 0.002, 4), round(depth + 0.001, 4)],
        "contact": list(WALLS),
    }
    task = {
        "task": "pin_insert",
        "steps": [
            {"move": "home"},
            {
                "pick": {
                    "at": "infeed",
                    "approach": cellgen.APPROACH_M,
                    "grip": {"confirm": "gripper_closed"},
                }
            },
            {"approach": {"to": "hole", "distance": APPROACH_ABOVE_M}},
            {"descend": {"to": "hole", "contact": list(WALLS)}},
            {"insert": insert},
            "release",
            {"retreat": cellgen.APPROACH_M},
            {"move": "home"},
        ],
    }
    witness = {"pick": cellgen._deg(d["q_pick"]), "place": cellgen._deg(d["q_place"])}
    return cellgen.Case(seed, kind, cell, task, witness)


def _witness_clear(case: Any, d: dict[str, Any]) -> bool:
    """The pick witness's line down and the place witness's line from the insert's end up
    through the approach over the hole and the retreat keep every checked pair
    :data:`bench.cellgen.WITNESS_MARGIN_M` clear of its clearance, the pin and the hole
    block excepted, and joint paths join them to home (``cellgen.joint_paths_exist``)."""
    import tempfile
    from pathlib import Path

    from bench import cellgen
    from cellrunner.model.load import load_cell
    from cellrunner.planning.world import CellWorld

    block = {*WALLS, "hole_floor", "pin"}
    with tempfile.TemporaryDirectory() as folder:
        cell, _ = case.write(Path(folder))
        world = CellWorld(load_cell(cell))
        collision = world.collision
        keep = np.array(
            [
                not any(b in f"{a} {c}" for b in block) and "part" not in f"{a} {c}"
                for a, c in collision.pair_labels
            ]
        )
        kin = d["kin"]
        lines = (
            (d["q_pick"], 0.0, cellgen.APPROACH_M),
            # from the insert's end up to the higher of the approach over the hole and
            # the retreat's end (the retreat rises from the insert's end)
            (d["q_place"], -d["depth"], max(APPROACH_ABOVE_M, cellgen.APPROACH_M - d["depth"])),
        )
        tops = []
        for q, below_m, above_m in lines:
            T_goal, config = kin.T_world_tcp(q), q
            steps = int((above_m - below_m) / 0.005) + 1
            for k in range(steps):
                config = kin.ik_track(T_goal @ cellgen._up(below_m + k * 0.005), config)
                if config is None:
                    return False
                distances, required = collision.pair_distances(config)
                if np.any((distances - required)[keep] < cellgen.WITNESS_MARGIN_M):
                    return False
            tops.append(config)
        return cellgen.joint_paths_exist(world, d["q_pick"], tops[0], tops[1])
