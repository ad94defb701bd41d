"""Chamfered holes in generated cells (bench/cellgen_chamfers.py, issue 33): each hole
kind drawn again with its walls bevelled, as convex STL meshes beside the cell; check and
the twin agree on them with the truth of the plain kinds (an arm held in position is not
steered by a chamfer: a centred pin goes in, a tip on the chamfer jams).

The two cells in tests/data/generated are as the generator wrote them when the harness
first ran on chamfers: walls named in ``contact:`` as meshes made check fail with an
internal error (coal cannot take a negative security margin on a triangle surface, and
a convex wall was one), which the harness counted as a refusal."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bench.agreement import cli
from bench.cellgen import generate
from bench.cellgen_chamfers import (
    CHAMFER_M,
    CHAMFERED,
    CHAMFERED_KINDS,
    INWARD,
    RIM_OVERLAP_M,
)
from cellrunner.planning.mesh_hull import convexity
from cellrunner.planning.stl import stl_triangles
from tests.agreement.generated import approved_and_rehearsed, copied

SEED = 11


def _volume_m3(triangles: np.ndarray) -> float:
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum()) / 6.0


def _pair(kind: str, tmp_path: Path):
    """The chamfered case of SEED and the plain one it was drawn from, written out."""
    chamfered, plain = generate(SEED, kind), generate(SEED, CHAMFERED[kind])
    chamfered.write(tmp_path / "chamfered")
    return chamfered, plain


@pytest.mark.parametrize("kind", CHAMFERED_KINDS)
def test_a_chamfered_case_is_its_plain_case_with_bevelled_convex_walls(kind, tmp_path):
    chamfered, plain = _pair(kind, tmp_path)
    again = generate(SEED, kind)
    assert (again.cell, again.task, again.files) == (
        chamfered.cell,
        chamfered.task,
        chamfered.files,
    )
    assert chamfered.task == plain.task  # the walls still named in contact:
    walls = {f["name"]: f for f in chamfered.cell["fixtures"]}
    boxes = {f["name"]: f for f in plain.cell["fixtures"]}
    assert [f["name"] for f in chamfered.cell["fixtures"]] == list(boxes)
    for name, fixture in walls.items():
        if name not in INWARD:
            assert fixture == boxes[name]
            continue
        assert fixture["mesh"] == {"file": f"meshes/{name}.stl"}
        assert fixture["pose"] == boxes[name]["pose"]
        triangles = stl_triangles(tmp_path / "chamfered" / fixture["mesh"]["file"])
        size = np.asarray(boxes[name]["box"]["size"])
        corners = triangles.reshape(-1, 3)
        assert np.allclose(corners.max(axis=0) - corners.min(axis=0), size, atol=1e-6)
        assert convexity(triangles) is True
        assert _volume_m3(triangles) > 0  # wound outward
        # the bevel takes c^2/2 along the edge that faces the hole: c 1-3 mm
        length_m = size[1] if INWARD[name][0] else size[0]
        c_m = math.sqrt(2 * (float(np.prod(size)) - _volume_m3(triangles)) / length_m)
        assert CHAMFER_M[0] - 2e-5 <= c_m <= CHAMFER_M[1] + 2e-5
        # on the face towards the hole: the top is c back from it, the face stops c below
        inward = np.array([*INWARD[name], 0.0])
        top = corners[np.isclose(corners[:, 2], size[2] / 2, atol=1e-6)]
        assert float(np.max(top @ inward)) == pytest.approx(
            float(np.abs(inward) @ size) / 2 - c_m, abs=2e-5
        )
    frames = dict(chamfered.cell["frames"])
    if kind != "jam_rim_chamfered":
        assert frames == plain.cell["frames"]


def test_the_jam_rim_tip_lands_on_the_chamfer_or_the_rim_past_it(tmp_path):
    """Over seeds, the tip is 0.3 mm to the chamfer's width + 0.5 mm over the inner face of
    wall_xp: mostly on the slope, sometimes on the flat rim."""
    where = []
    for seed in range(SEED, SEED + 6):
        case = generate(seed, "jam_rim_chamfered")
        walls = {f["name"]: f for f in case.cell["fixtures"]}
        floor = np.asarray(walls["hole_floor"]["pose"]["xyz"][:2])
        xp = np.asarray(walls["wall_xp"]["pose"]["xyz"][:2])
        ux = (xp - floor) / np.linalg.norm(xp - floor)
        face_m = float(np.linalg.norm(xp - floor)) - 0.01  # the walls are 20 mm thick
        pin_half_m = case.cell["parts"][0]["box"]["size"][0] / 2
        centre_m = float((np.asarray(case.cell["frames"]["hole"]["xyz"][:2]) - floor) @ ux)
        overlap_m = centre_m + pin_half_m - face_m
        folder = tmp_path / str(seed)
        case.write(folder)
        triangles = stl_triangles(folder / "meshes" / "wall_xp.stl")
        c_m = math.sqrt(2 * (0.02 * 0.04 * _length(walls) - _volume_m3(triangles)) / _length(walls))
        assert RIM_OVERLAP_M[0] - 2e-5 <= overlap_m <= c_m + RIM_OVERLAP_M[1] + 2e-5
        where.append("slope" if overlap_m < c_m else "rim")
    assert "slope" in where


def _length(walls: dict) -> float:
    """wall_xp's length along the hole's side (m): the hole and both y walls."""
    ym, yp = (np.asarray(walls[n]["pose"]["xyz"][:2]) for n in ("wall_ym", "wall_yp"))
    return float(np.linalg.norm(yp - ym)) + 0.02


def test_a_centred_pin_goes_into_a_chamfered_hole_in_check_and_the_twin(tmp_path):
    """s100, a UR5e: the pin with 0.25-3 mm of clearance, centred over walls bevelled at
    45 deg: check approves the insert along the convex walls and the twin ends 0 with the
    pin let go in its hole, standing on its floor."""
    from ruamel.yaml import YAML

    cell, task = copied("s100-ur5e-chamfered-fit", tmp_path)
    _, run = approved_and_rehearsed(cell, task)
    data = YAML(typ="safe").load(Path(cell))
    hole = data["frames"]["hole"]["xyz"]
    pin = run["parts_end_m"]["pin"]
    assert math.dist(pin[:2], hole[:2]) < 0.002
    floor = next(f for f in data["fixtures"] if f["name"] == "hole_floor")
    on_floor_z = floor["pose"]["xyz"][2] + floor["box"]["size"][2] / 2
    assert pin[2] == pytest.approx(on_floor_z + data["parts"][0]["box"]["size"][2] / 2, abs=0.001)


def test_check_refuses_a_tip_on_the_chamfer_as_a_jam_on_the_rim(tmp_path):
    """s106, a UR10: the pin's tip 0.54 mm over the inner face of wall_xp, whose chamfer is
    2.4 mm wide: it meets the slope 1.9 mm down, and an arm held in position cannot slide
    along it; check names the wall and where, and the fix moves the frame past the rim."""
    cell, task = copied("s106-ur10-chamfered-rim", tmp_path)
    code, out = cli("check", cell, task, "--no-cache")
    assert code == 1
    (error,) = out["errors"]
    assert "part 'pin' comes 0.5" in error
    assert "mm over the rim of fixture 'wall_xp' 1.9 mm past frame 'hole'" in error
    assert "it jams on the rim; fix: centre frame 'hole' over the hole (move it 0.6 mm" in error


def test_the_twin_jams_a_tip_on_the_chamfer(tmp_path, twin_only):
    """The same job in the twin alone: the pin's edge meets the rigid, convex slope and
    the insert stops at its force limit short of expect_depth (3), as on a plain rim."""
    cell, task = copied("s106-ur10-chamfered-rim", tmp_path)
    _, out = cli("dry-run", cell, task)
    assert out["result_code"] == 3, out
    assert out["result_text"].startswith("inserted "), out
    inserted_mm = float(out["result_text"].split()[1])
    assert 1.0 < inserted_mm < 3.0  # on the slope 1.9 mm down, not in the bore


def test_a_tip_far_over_the_chamfer_is_refused_as_a_jam_not_as_a_press(tmp_path):
    """The same cell with frame 'hole' 1.6 mm further towards wall_xp: the tip 2.14 mm
    over its face meets the 2.4 mm chamfer 0.3 mm down and presses in further than the
    1 mm a named fixture may be pressed into. check said so ('presses 0.92 mm into
    fixture 'wall_xp', 0.02 mm more than the 0.90 mm it may 0 mm along the line'); it now
    says what that is, a jam, with the distance that clears the rim."""
    from ruamel.yaml import YAML

    cell, task = copied("s106-ur10-chamfered-rim", tmp_path)
    yaml = YAML()
    data = yaml.load(Path(cell))
    walls = {f["name"]: f for f in data["fixtures"]}
    floor = np.asarray(walls["hole_floor"]["pose"]["xyz"][:2], float)
    ux = np.asarray(walls["wall_xp"]["pose"]["xyz"][:2], float) - floor
    ux /= np.linalg.norm(ux)
    hole = data["frames"]["hole"]["xyz"]
    hole[0], hole[1] = (round(float(v), 5) for v in np.asarray(hole[:2]) + 0.0016 * ux)
    with Path(cell).open("w") as out:
        yaml.dump(data, out)
    code, out = cli("check", cell, task, "--no-cache")
    assert code == 1
    (error,) = out["errors"]
    assert "part 'pin' comes 2.1" in error
    assert "mm over the rim of fixture 'wall_xp' 0.3 mm past frame 'hole'" in error
    assert "it jams on the rim; fix: centre frame 'hole' over the hole (move it 2.2 mm" in error
