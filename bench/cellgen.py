"""A generator of cells and jobs with their ground truth, for testing ``check`` and the
twin on cells nobody on the team wrote (issue 33).

``generate(seed)`` writes, from one seed and reproducibly, a pick-and-place cell a line
would have: one of the arms on a pedestal, hanging from the ceiling or on a wall, a jaw gripper whose stroke fits the part, a part
on an infeed table, an outfeed table, and a job ``move home -> pick -> place -> move
home``. Frames are placed from **witness** joint configurations: for each target the
generator first picks joint angles in the arm's working region (the wrist down, the elbow
up), then puts the frame where forward kinematics takes the TCP, and the table under it;
so a job without a defect is feasible by construction: an arm that stands there exists,
and the straight lines down to the frames keep 5 mm over every clearance.

``generate(seed, defect)`` breaks that job in one way, the ground truth of what a correct
``check`` (and twin) must say:

- ``out_of_reach``: the outfeed moved out past the arm's reach;
- ``unsupported_place``: the place lets the part go 30 mm above the outfeed table;
- ``into_support``: the place pushes the part 8 mm into the outfeed table;
- ``jaws_too_narrow``: the gripper's stroke is narrower than the part;
- ``weak_vacuum``: the cups hold less than the part weighs;
- ``blocked_layer``: the place is the upper of two layers whose pitch is 10 mm under the
  part's height (it would go into the part an earlier job put below);
- ``blocked_column``: the place is the second of two columns whose pitch is 1-8 mm under
  the part's width (it would come down onto the part an earlier job put beside it).

and ``near_support`` is a feasible variant that sets the part down 2 mm above its table,
``layered`` one that sets it 2 mm above the part an earlier job put on the layer below
and ``interlocked`` the same on an interlocked pallet, the upper layer turned 90 deg
(``turn: [0, 90]``, SPEC section 13) (places a line engineer writes, which ``check``
must not refuse). ``recovering`` is the feasible job with an ``on_error`` (the gripper's
output off, a 50 mm retreat, home), rehearsed with the part slipping out of the gripper
as it is lifted: the twin must end it 2 (part lost) with on_error done from
where the arm stopped, as ``check`` proved it from every state a fault can leave.

The kinds of :mod:`bench.cellgen_holes` (a pin into a hole: a fit, a hole too shallow, a
rim and an interference jam) are generated there, and each again with chamfered walls in
:mod:`bench.cellgen_chamfers` (``hole_fit_chamfered``, ...).

Run ``python bench/cellgen.py SEED [DEFECT] DIR`` to write one case's files.
"""

from __future__ import annotations

import math
import random
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench import cellgen_chamfers, cellgen_holes
from bench.cellgen_cameras import (
    ALIGN_KINDS,
    CAMERA_DEFECTS,
    CAMERA_FEASIBLE,
    CAMERA_KINDS,
    NEEDS_JAWS,
    align_witness_clear,
    with_cameras,
)

#: the arms the generator mounts (the pedestal's height, m)
ARMS = ("ur3e", "ur5e", "ur10e", "ur16e", "ur5", "ur10")
PEDESTAL_M = 0.90
#: how the arm is mounted: base position (m) and rpy (deg) in the world, and where its
#: targets lie below the base (fractions of the reach). Floor: on a pedestal, the targets
#: around the shoulder's height; ceiling: hanging from a plate, the targets well below
MOUNTS: dict[
    str, tuple[tuple[float, float, float], tuple[float, float, float], tuple[float, float]]
] = {
    "floor": ((0.0, 0.0, PEDESTAL_M), (0.0, 0.0, 0.0), (-0.25, 0.05)),
    "ceiling": ((0.0, 0.0, 2.0), (180.0, 0.0, 0.0), (-0.75, -0.45)),
    # on a wall (the plane x = 0), the base's Z along world +X: the targets in front of
    # the wall, below the base
    "wall": ((0.0, 0.0, 1.4), (0.0, 90.0, 0.0), (-0.55, -0.25)),
}
CEILING_SHARE, WALL_SHARE = 0.3, 0.15
#: feasible kinds of jobs, and the defects (each breaks one thing)
#: feasible kinds added after the fixed sample was drawn (sampled on seeds of their own)
LATER_FEASIBLE = ("interlocked", "recovering")
#: and the declared press fits, feasible and broken (bench/cellgen_holes.py)
PRESS_KINDS = cellgen_holes.PRESS_KINDS
#: defects added after the fixed sample was drawn (sampled on seeds of their own)
LATER_DEFECTS = ("blocked_column",)
#: the kinds added since the fixed sample's first part: on seeds of their own
ADDED_KINDS = (*PRESS_KINDS, *LATER_DEFECTS, *cellgen_chamfers.CHAMFERED_KINDS)
FEASIBLE = (
    "feasible",
    "near_support",
    "layered",
    *CAMERA_FEASIBLE,
    *cellgen_holes.HOLE_FEASIBLE,
    *LATER_FEASIBLE,
    *cellgen_holes.PRESS_FEASIBLE,
    *cellgen_chamfers.CHAMFERED_FEASIBLE,
)
DEFECTS = (
    "out_of_reach",
    "unsupported_place",
    "into_support",
    "jaws_too_narrow",
    "weak_vacuum",
    "blocked_layer",
    *CAMERA_DEFECTS,
    *cellgen_holes.HOLE_DEFECTS,
    *cellgen_holes.PRESS_DEFECTS,
    *LATER_DEFECTS,
    *cellgen_chamfers.CHAMFERED_DEFECTS,
)
#: the kinds that place on a pattern of two layers, the job's part on the upper one (on
#: the part an earlier job put on the lower): ``layered`` 2 mm above it, ``blocked_layer``
#: with a layer pitch 10 mm under the part's height (it would go into the part below)
LAYERED = {"layered": 0.002, "blocked_layer": -0.010, "interlocked": 0.002}
#: the kinds whose upper layer turns about the frame's Z (deg): an interlocked pallet
TURNED = {"interlocked": 90.0}
KINDS = FEASIBLE + DEFECTS
#: the kinds without cameras (the fixed sample's first part keeps its seeds), and without
#: those added since (sampled on seeds of their own)
PLAIN_KINDS = tuple(
    k for k in KINDS if k not in CAMERA_KINDS and k not in LATER_FEASIBLE and k not in ADDED_KINDS
)
#: the kinds that need one gripper: the others draw jaws or cups (VACUUM_SHARE of them cups)
NEEDS_GRIPPER = {"jaws_too_narrow": "jaws", "weak_vacuum": "vacuum", **NEEDS_JAWS}
VACUUM_SHARE = 0.4
TABLE_THICKNESS_M = 0.04
GRAVITY_MPS2 = 9.81
#: the seal's load per kg of part when the arm brakes at its limits (N/kg, see _draw_cups)
FULL_ACCEL_PULL_N_PER_KG = 110.0


@dataclass
class Case:
    """One generated job: its files' contents and what a correct ``check`` says."""

    seed: int
    kind: str  # "feasible", "near_support" or a defect
    cell: dict[str, Any]
    task: dict[str, Any]
    witness_deg: dict[str, list[float]] = field(default_factory=dict)
    #: what the rehearsal adds to ``dry-run`` (a fault it injects) and the result code it
    #: must end with then (with ``on_error`` done where it injects one)
    rehearse: tuple[str, ...] = ()
    expect_code: int = 0
    #: files the cell names beside it (a mesh fixture's STL): path relative to the cell
    #: file's folder -> contents
    files: dict[str, bytes] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return f"s{self.seed}-{self.cell['robot']['model']}-{self.kind}"

    @property
    def feasible(self) -> bool:
        return self.kind in FEASIBLE

    def write(self, folder: Path) -> tuple[Path, Path]:
        """Write ``cell.yaml`` and ``task.yaml`` into ``folder`` (and the files the cell
        names beside it); their paths."""
        folder.mkdir(parents=True, exist_ok=True)
        for relative, contents in self.files.items():
            (folder / relative).parent.mkdir(parents=True, exist_ok=True)
            (folder / relative).write_bytes(contents)
        cell, task = folder / "cell.yaml", folder / "task.yaml"
        for path, data in ((cell, self.cell), (task, self.task)):
            with path.open("w") as out:
                out.write(f"# generated: seed {self.seed}, {self.kind}\n")
                _yaml().dump(data, out)
        return cell, task


def _yaml() -> Any:
    from ruamel.yaml import YAML

    writer = YAML()
    writer.default_flow_style = None  # short lists and maps on one line
    return writer


def _kinematics(model: str, tcp_m: float, mount: str = "floor") -> Any:
    from cellrunner.model.geometry import pose_matrix
    from cellrunner.model.robots import robot_spec
    from cellrunner.planning.kinematics import ArmKinematics

    xyz, rpy, _ = MOUNTS[mount]
    T_flange_tcp = np.eye(4)
    T_flange_tcp[2, 3] = tcp_m
    return ArmKinematics(robot_spec(model), pose_matrix(xyz, rpy), T_flange_tcp)


def _witness(
    rng: random.Random, kin: Any, base_deg: float, reach_m: float, mount: str = "floor"
) -> np.ndarray:
    """Joint angles (rad) with the tool pointing straight down, the elbow bent the
    working way (up on a pedestal, towards the ceiling when hanging), the TCP at a
    comfortable radius and height: a configuration that exists."""
    spec = kin.spec
    (_, _, base_z), _, (low, high) = MOUNTS[mount]
    if mount == "wall":  # in front of the wall, on the side base_deg is on
        base_deg = math.copysign(rng.uniform(20, 60), base_deg)
    for _ in range(200):
        radius = rng.uniform(0.45, 0.75) * reach_m
        height = base_z + rng.uniform(low, high) * reach_m
        yaw = rng.uniform(-60, 60)
        T = _down_pose(base_deg, radius, height, yaw)
        branches = kin.ik_all(T, np.radians(HOME_DEG))
        for q in branches:
            q = np.asarray(q, float)
            if mount == "wall" or (q[2] > 0.2 and q[1] < -0.2):
                # elbow up, shoulder raised: the working branch (on a wall, the branch
                # nearest home; the witness check below proves it clear)
                return q
    raise RuntimeError(f"no witness for {spec.name} at base {base_deg} deg")


HOME_DEG = (0.0, -90.0, 90.0, -90.0, -90.0, 0.0)


def _down_pose(base_deg: float, radius_m: float, z_m: float, yaw_deg: float) -> np.ndarray:
    """The TCP pointing down (-Z world) at ``radius_m`` from the base axis, bearing
    ``base_deg``, height ``z_m``, turned ``yaw_deg`` about the vertical."""
    from scipy.spatial.transform import Rotation

    b = math.radians(base_deg)
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", [180, 0, base_deg + yaw_deg], degrees=True).as_matrix()
    T[:3, 3] = (radius_m * math.cos(b), radius_m * math.sin(b), z_m)
    return T


def _rpy_deg(T: np.ndarray) -> list[float]:
    from scipy.spatial.transform import Rotation

    return [
        round(float(a), 4) for a in Rotation.from_matrix(T[:3, :3]).as_euler("xyz", degrees=True)
    ]


def _xyz(T: np.ndarray) -> list[float]:
    return [round(float(v), 5) for v in T[:3, 3]]


def _table(name: str, T_frame: np.ndarray, top_z_m: float, side_m: float = 0.30) -> dict[str, Any]:
    """A square table ``side_m`` wide whose top is at ``top_z_m`` under the frame."""
    x, y, top_z_m = float(T_frame[0, 3]), float(T_frame[1, 3]), float(top_z_m)
    return {
        "name": name,
        "box": {"size": [side_m, side_m, TABLE_THICKNESS_M]},
        "pose": {"xyz": [round(x, 5), round(y, 5), round(top_z_m - TABLE_THICKNESS_M / 2, 5)]},
    }


#: a witness configuration keeps every checked pair of the arm and tool this much clear of
#: what it must keep (m), the waiting part excepted (the jaws stand around it)
WITNESS_MARGIN_M = 0.005
#: how many draws a seed may take to find witnesses that keep that margin
WITNESS_TRIES = 100


def generate(seed: int, kind: str = "feasible") -> Case:
    """The case of ``seed`` broken (or not) as ``kind`` says (one of :data:`KINDS`)."""
    if kind not in KINDS:
        raise ValueError(f"unknown case kind {kind!r}; known: {', '.join(KINDS)}")
    if kind in cellgen_holes.HOLE_KINDS:  # a pin into a hole (bench/cellgen_holes.py)
        return cellgen_holes.generate(seed, kind)
    if kind in cellgen_chamfers.CHAMFERED:  # and into a chamfered one
        return cellgen_chamfers.generate(seed, kind)
    rng = random.Random(seed)
    # the mount is drawn once: a wall's witnesses fail more often than a floor's, and
    # drawing it again with the rest would leave the walls out
    r = rng.random()
    mount = (
        "ceiling" if r < CEILING_SHARE else "wall" if r < CEILING_SHARE + WALL_SHARE else "floor"
    )
    for _ in range(WITNESS_TRIES):
        draw = _draw(rng, kind, mount)
        if not _witnesses_clear(draw):
            continue
        case = _case(seed, kind, draw)
        # an align corrects the pick and looks first: the witness keeps its margins for
        # every correction check proves, and at the look (bench/cellgen_cameras.py)
        if kind in ALIGN_KINDS and not align_witness_clear(
            case, draw.q_pick, APPROACH_M, WITNESS_MARGIN_M
        ):
            continue
        return case
    raise RuntimeError(f"seed {seed}: no witnesses {WITNESS_MARGIN_M * 1000:g} mm clear")


@dataclass
class _Draw:
    """One draw of the feasible job: the arm, the part, the jaws and the two witnesses."""

    model: str
    reach_m: float
    tcp_m: float
    size: list[float]
    mass: float
    stroke: float
    kin: Any
    q_pick: np.ndarray
    q_place: np.ndarray
    gripper: str = "jaws"  # or "vacuum": cups on the part's top face
    mount: str = "floor"  # or "ceiling", "wall" (MOUNTS)
    cups: list[dict[str, Any]] = field(default_factory=list)
    holding_N: float = 0.0
    #: how far above the place's witness the job's place lies (a layered pattern's upper
    #: layer, m): the witness's line down is proven from that height plus the approach
    rise_m: float = 0.0
    #: how far the upper layer turns about the place frame's Z (deg, ``TURNED``)
    turn_deg: float = 0.0
    #: a blocked column's pitch under the part's width (m)
    column_overlap_m: float = 0.0


def _draw(rng: random.Random, kind: str, mount: str) -> _Draw:
    from cellrunner.model.robots import robot_spec

    model = rng.choice(ARMS)
    gripper = NEEDS_GRIPPER.get(kind) or ("vacuum" if rng.random() < VACUUM_SHARE else "jaws")
    reach_m = robot_spec(model).reach_m
    tcp_m = round(rng.uniform(0.12, 0.18), 3)
    kin = _kinematics(model, tcp_m, mount)
    # the jaws' pads reach 20 mm below the TCP (the part's centre): a part tall enough
    # that they stay 10 mm or more above the table it stands on
    size = [round(rng.uniform(0.03, 0.06), 3) for _ in range(2)]
    size.append(round(rng.uniform(0.06, 0.08), 3))
    mass = round(rng.uniform(0.2, 1.0), 2)
    # the jaws close along the TCP's X, which is the part's X (it lies in its frame's axes)
    stroke = round(size[0] + rng.uniform(0.02, 0.04), 3)
    q_pick = _witness(rng, kin, rng.uniform(-150, -40), reach_m, mount)
    q_place = _witness(rng, kin, rng.uniform(40, 150), reach_m, mount)
    draw = _Draw(model, reach_m, tcp_m, size, mass, stroke, kin, q_pick, q_place, gripper)
    draw.mount = mount
    if gripper == "vacuum":
        _draw_cups(rng, draw)
    if kind in LAYERED:
        draw.rise_m = round(draw.size[2] + LAYERED[kind], 4)
        draw.turn_deg = TURNED.get(kind, 0.0)
    if kind == "blocked_column":  # drawn last: the other kinds keep their draws
        draw.column_overlap_m = round(rng.uniform(0.001, 0.008), 4)
    return draw


def _draw_cups(rng: random.Random, d: _Draw) -> None:
    """One, two or four cups on the part's top face, and cups that hold the part through
    the carrying moves at the arm's full acceleration (up to ~5 g at a UR10e's TCP, whose
    shear the cups hold by friction, 0.5: ~110 N per kg) and 20 N more."""
    d.size = [round(rng.uniform(0.08, 0.20), 3), round(rng.uniform(0.08, 0.16), 3)]
    d.size.append(round(rng.uniform(0.05, 0.12), 3))
    d.mass = round(rng.uniform(0.5, 3.0), 2)
    radius = round(rng.uniform(0.01, 0.02), 3)
    n = rng.choice((1, 2, 4))
    dx, dy = (d.size[0] / 2 - radius - 0.005), (d.size[1] / 2 - radius - 0.005)
    spots = {1: [(0, 0)], 2: [(dx, 0), (-dx, 0)], 4: [(dx, dy), (dx, -dy), (-dx, dy), (-dx, -dy)]}
    d.cups = [{"xyz": [round(x, 4), round(y, 4), 0], "radius": radius} for x, y in spots[n]]
    d.holding_N = round(rng.uniform(1.0, 1.5) * d.mass * FULL_ACCEL_PULL_N_PER_KG + 20, 1)


def _witnesses_clear(draw: _Draw) -> bool:
    """Both witnesses, the straight lines down to them from their approach points, and
    home keep every checked pair :data:`WITNESS_MARGIN_M` clear of its required clearance
    (the part excepted), and on those lines the part as carried keeps it from the arm's
    links (a lift or a set-down where the arm folds onto its load is no witness)."""
    import tempfile

    from cellrunner.model.load import load_cell
    from cellrunner.planning.world import CellWorld

    with tempfile.TemporaryDirectory() as folder:
        cell, _ = _case(0, "feasible", draw).write(Path(folder))
        world = CellWorld(load_cell(cell))
        held = world.part_at("infeed", draw.kin.T_world_tcp(draw.q_pick))
        collision = world.collision.carrying(held)
        labels = collision.pair_labels
        keep = np.array(
            [
                ("part" not in a and "part" not in b) or {a.kind.name, b.kind.name} == _ARM_LOAD
                for a, b in labels
            ]
        )
        # the straight lines from the approach points down to the witnesses (the place's
        # from above the upper layer, and turned with it on an interlocked pallet)
        lines = [(draw.q_pick, 0.0, APPROACH_M), (draw.q_place, 0.0, APPROACH_M + draw.rise_m)]
        if draw.turn_deg:
            lines.append((draw.q_place, draw.turn_deg, APPROACH_M + draw.rise_m))
        tops = [_line_top(draw.kin, collision, keep, *line) for line in lines]
        if any(top is None for top in tops):
            return False
        # and home, where the job starts and ends (on a wall, the tables may come near it)
        distances, required = collision.pair_distances(np.radians(HOME_DEG))
        if np.any((distances - required)[keep] < WITNESS_MARGIN_M):
            return False
        return joint_paths_exist(world, draw.q_pick, tops[0], tops[-1])
    return True


def _line_top(
    kin: Any, collision: Any, keep: np.ndarray, q: np.ndarray, turn_deg: float, top_m: float
) -> np.ndarray | None:
    """The configuration at the top of the straight line up ``top_m`` from witness ``q``
    (its pose turned ``turn_deg`` about the TCP's Z), tracked back up every 5 mm, when the
    whole line keeps its margins (:func:`keeps_margins`); else None."""
    T_goal, config = kin.T_world_tcp(q) @ _turn(turn_deg), q
    if turn_deg:  # the wrist's last joint turns the TCP about its Z
        config = kin.ik_track(T_goal, q + np.radians([0, 0, 0, 0, 0, turn_deg]))
        if config is None or not kin.within_limits(config):
            return None
    for k in range(int(top_m / 0.005) + 1):
        config = kin.ik_track(T_goal @ _up(k * 0.005), config)
        if not keeps_margins(kin, collision, keep, config):
            return None
    return np.asarray(config)


def keeps_margins(
    kin: Any,
    collision: Any,
    keep: np.ndarray,
    q: np.ndarray | None,
    margin_m: float = WITNESS_MARGIN_M,
) -> bool:
    """A witness's configuration ``q`` (None: none found) keeps every checked pair
    (``keep``) ``margin_m`` over its clearance and the wrist, elbow and shoulder
    :data:`WITNESS_SINGULAR_DEG` and :data:`WITNESS_SHOULDER_M` farther from their
    singularities than the planner requires."""
    from cellrunner.planning.cartesian import MIN_SHOULDER_DISTANCE_M, MIN_SINGULARITY_ANGLE_DEG

    if q is None or kin.singularity_distance(q).violation(
        MIN_SINGULARITY_ANGLE_DEG + WITNESS_SINGULAR_DEG,
        MIN_SHOULDER_DISTANCE_M + WITNESS_SHOULDER_M,
    ):
        return False
    distances, required = collision.pair_distances(q)
    return bool(np.all((distances - required)[keep] >= margin_m))


#: how much farther than ``check`` requires a witness keeps the wrist and elbow from
#: their singularities (deg), and the wrist point from the shoulder's (m)
WITNESS_SINGULAR_DEG, WITNESS_SHOULDER_M = 2.0, 0.01


def joint_paths_exist(
    world: Any, q_grip: np.ndarray, q_pick_top: np.ndarray, q_place_top: np.ndarray
) -> bool:
    """A collision-free joint path is found from home to the pick's approach point, on to
    the place's (the part carried, as gripped at ``q_grip``) and back home: without one the approach points are no
    witness (on a wall, the upper arm may have to pass through the plate to get there).
    A path found is a witness; the planner ``check`` uses searches far longer here."""
    from cellrunner.errors import InfeasibleError
    from cellrunner.planning.joint_path import plan_joint_path

    home = np.radians(HOME_DEG)
    carrying = world.collision.carrying(
        world.part_at("infeed", world.kinematics.T_world_tcp(q_grip))
    )
    legs = (
        (world.collision, home, q_pick_top),
        (carrying, q_pick_top, q_place_top),
        (world.collision, q_place_top, home),
    )
    try:
        for collision, q0, q1 in legs:
            plan_joint_path(collision, q0, q1, time_budget_s=WITNESS_PATH_S, proven=False)
    except InfeasibleError:
        return False
    return True


#: how long a witness's joint path is searched for (s)
WITNESS_PATH_S = 10.0


#: the pairs of an arm's link and its carried part
_ARM_LOAD = {"ROBOT_LINK", "PART"}


def _turn(deg: float) -> np.ndarray:
    """About the frame's Z by ``deg`` (a pattern layer's turn)."""
    T = np.eye(4)
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    T[:2, :2] = [[c, -s], [s, c]]
    return T


def _up(distance_m: float) -> np.ndarray:
    """Back along the TCP's -Z by ``distance_m`` (the approach point above a frame)."""
    T = np.eye(4)
    T[2, 3] = -distance_m
    return T


#: how far above its frame a pick or place approaches (m)
APPROACH_M = 0.08


def _case(seed: int, kind: str, d: _Draw) -> Case:
    """The files of draw ``d``, broken as ``kind`` says."""
    T_pick, T_place = d.kin.T_world_tcp(d.q_pick), d.kin.T_world_tcp(d.q_place)
    # the jaws hold the part at its centre, the cups at its top face
    below = d.size[2] if d.gripper == "vacuum" else d.size[2] / 2
    pick_top, place_top = T_pick[2, 3] - below, T_place[2, 3] - below
    stroke = d.stroke
    holding_N = d.holding_N
    if kind == "near_support":
        place_top -= 0.002  # the part is let go 2 mm above the table
    elif kind == "unsupported_place":
        place_top -= 0.030
    elif kind == "into_support":
        place_top += 0.008
    elif kind == "out_of_reach":
        scale = 1.35 * d.reach_m / float(np.linalg.norm(T_place[:2, 3]))
        T_place = T_place.copy()
        T_place[:2, 3] *= scale
    elif kind == "jaws_too_narrow":
        stroke = round(d.size[0] * 0.7, 3)
    elif kind == "weak_vacuum":  # the cups hold less than the part weighs
        holding_N = round(random.Random(seed).uniform(0.4, 0.9) * d.mass * GRAVITY_MPS2, 1)
    # a blocked column: the job's place is the second column, on the witness; the first,
    # an earlier job's part, a pitch under the part's width along the frame's Y, and the
    # table under both
    column_pitch_m = round(d.size[1] - d.column_overlap_m, 4)
    T_frame, T_table, table_m = T_place, T_place, 0.30
    if kind == "blocked_column":
        T_frame, T_table = T_place.copy(), T_place.copy()
        T_frame[:3, 3] -= column_pitch_m * T_place[:3, 1]
        T_table[:3, 3] -= column_pitch_m / 2 * T_place[:3, 1]
        table_m = 0.45
    tcp_m = d.tcp_m
    if d.gripper == "vacuum":
        # the cups' body ends 30 mm above the TCP (the cups' faces, 20 mm long)
        body_m, body_r = round(tcp_m - 0.03, 3), 0.03
        gripper: dict[str, Any] = {
            "kind": "vacuum",
            "suction": {"output": "vacuum_on", "value": True},
            "vacuum_ok": "vacuum_ok",
            "cups": d.cups,
            "holding_force": holding_N,
        }
        io = {"outputs": {"vacuum_on": "DO0"}, "inputs": {"vacuum_ok": "DI0"}}
        grip = {"confirm": "vacuum_ok"}
    else:
        body_m = round(tcp_m - 0.06, 3)  # the gripper's body, flange to 60 mm above the TCP
        body_r = round(max(0.03, stroke / 2 + 0.015), 3)
        gripper = {
            "kind": "io",
            "close": {"output": "gripper_close", "value": True},
            "closed_sensor": "gripper_closed",
            "stroke": stroke,
        }
        io = {"outputs": {"gripper_close": "DO0"}, "inputs": {"gripper_closed": "DI0"}}
        grip = {"confirm": "gripper_closed"}
    cell = {
        "cell": f"gen-{seed}-{kind}",
        "robot": {
            "model": d.model,
            "host": "127.0.0.2",
            "backend": "sim",
            "mount": {"xyz": list(MOUNTS[d.mount][0]), "rpy": list(MOUNTS[d.mount][1])},
            "home": list(HOME_DEG),
        },
        "tool": {
            "tcp": {"xyz": [0, 0, tcp_m], "rpy": [0, 0, 0]},
            "payload": {"mass": 1.0, "cog": [0, 0, round(tcp_m / 3, 3)]},
            "gripper": gripper,
            "geometry": [
                {
                    "cylinder": {"radius": body_r, "length": body_m},
                    "xyz": [0, 0, round(body_m / 2, 4)],
                }
            ],
        },
        "io": io,
        "fixtures": [
            _base_fixture(d.mount),
            _table("infeed_table", T_pick, pick_top),
            _table("outfeed_table", T_table, place_top, table_m),
        ],
        "frames": {
            "infeed": {"xyz": _xyz(T_pick), "rpy": _rpy_deg(T_pick)},
            "outfeed": {"xyz": _xyz(T_frame), "rpy": _rpy_deg(T_frame)},
        },
        "parts": [{"name": "part", "box": {"size": d.size}, "mass": d.mass, "at": "infeed"}],
        "tasks": {1: "task.yaml"},
        "journal": "var/jobs.sqlite",
    }
    task = {
        "task": "pick_place",
        "steps": [
            {"move": "home"},
            {"pick": {"at": "infeed", "approach": APPROACH_M, "grip": grip}},
            {"place": {"at": "outfeed", "approach": APPROACH_M}},
            {"move": "home"},
        ],
    }
    if kind in LAYERED:  # the upper of two layers, on the part an earlier job put below
        task["params"] = {"slot": {"type": "int", "min": 0, "max": 1, "default": 1}}
        pattern: dict[str, Any] = {"grid": [1, 1, 2], "pitch": [0.1, 0.1, d.rise_m]}
        if d.turn_deg:  # interlocked: layer k turns by turn[k % 2]
            pattern = {"grid": [1, 1], "pitch": [0.1, 0.1], "layers": 2}
            pattern |= {"layer_pitch": d.rise_m, "turn": [0, d.turn_deg]}
        task["steps"][2]["place"]["pattern"] = {**pattern, "index": "slot"}
    if kind == "blocked_column":  # the second of two columns, beside an earlier job's part
        task["params"] = {"slot": {"type": "int", "min": 0, "max": 1, "default": 1}}
        pattern = {"grid": [1, 2, 1], "pitch": [0.1, column_pitch_m, 0.1], "index": "slot"}
        task["steps"][2]["place"]["pattern"] = pattern
    witness = {"pick": _deg(d.q_pick), "place": _deg(d.q_place)}
    case = Case(seed, kind, cell, task, witness)
    # the part slips out as it is lifted (it falls back under the gripper, which rises
    # away from it; slipped in the joint move after it, a UR10e's cups, falling faster
    # than the part, caught it again: s80027), and on_error clears up
    if kind == "recovering":
        off = "vacuum_on" if d.gripper == "vacuum" else "gripper_close"
        task["on_error"] = [{"set_output": {off: False}}, {"retreat": 0.05}, {"move": "home"}]
        case.rehearse, case.expect_code = ("--inject", "part_slip@lift"), 2
    return with_cameras(case, seed) if kind in CAMERA_KINDS else case


def _base_fixture(mount: str) -> dict[str, Any]:
    """What the arm stands on: a pedestal from the floor, or a plate on the ceiling or the
    wall."""
    if mount == "ceiling":
        z = MOUNTS[mount][0][2]
        return {
            "name": "ceiling_plate",
            "box": {"size": [0.4, 0.4, 0.02]},
            "pose": {"xyz": [0, 0, z + 0.02]},
        }
    if mount == "wall":
        z = MOUNTS[mount][0][2]
        return {
            "name": "wall_plate",
            "box": {"size": [0.02, 0.4, 0.4]},
            "pose": {"xyz": [-0.02, 0, z]},
        }
    return {
        "name": "pedestal",
        "cylinder": {"radius": 0.1, "length": PEDESTAL_M - 0.01},
        "pose": {"xyz": [0, 0, (PEDESTAL_M - 0.01) / 2]},
    }


def _deg(q_rad: np.ndarray) -> list[float]:
    return [round(float(v), 3) for v in np.degrees(q_rad)]


def corpus_seeds(count: int, seed: int, kinds: tuple[str, ...] = KINDS) -> list[tuple[int, str]]:
    """The seed and kind of ``count`` cases from ``seed``: the ``kinds`` in turn, each on
    its own seed."""
    return [(seed + i, kinds[i % len(kinds)]) for i in range(count)]


def corpus(count: int, seed: int, kinds: tuple[str, ...] = KINDS) -> list[Case]:
    """``count`` cases from ``seed`` (``corpus_seeds``)."""
    return [generate(s, kind) for s, kind in corpus_seeds(count, seed, kinds)]


if __name__ == "__main__":
    if len(sys.argv) not in (3, 4):
        sys.exit("usage: python bench/cellgen.py SEED [KIND] DIR")
    kind = sys.argv[2] if len(sys.argv) == 4 else "feasible"
    case = generate(int(sys.argv[1]), kind)
    print(*case.write(Path(sys.argv[-1])))
