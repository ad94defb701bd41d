"""A part lost in transit is not waiting at its frame any more (issue 33): check proves
on_error from the middle of every move that carries a part, with the part carried and
with it lost; the lost part's copy waiting at the infeed stayed in the cell, and a cleanup
move home from the middle of a wall-mounted UR16e's transfer was refused for starting
1.3 mm inside it (s100175, stored as the generator wrote it: a false refusal, the job
rehearsed with the part slipping out as it is lifted ends 2 with on_error done)."""

from __future__ import annotations

from bench.agreement import cli
from tests.agreement.generated import GENERATED, copied

NAME = "s100175-ur16e-recovering"


def test_on_error_from_a_lost_part_state_does_not_meet_the_parts_old_place(tmp_path):
    cell, task = copied(NAME, tmp_path)
    code, checked = cli("check", cell, task, "--no-cache")
    assert (code, checked["ok"]) == (0, True), checked
    assert not any("waiting part 'part'" in w for w in checked.get("warnings", [])), checked
    _, run = cli("dry-run", cell, task, "--inject", "part_slip@lift")
    assert run["result_code"] == 2, run
    assert "on_error done" in run["result_text"]


def test_a_lost_part_is_no_waiting_part_of_the_world_it_leaves():
    from cellrunner.model.load import load_cell
    from cellrunner.planning.world import CellWorld

    world = CellWorld(load_cell(GENERATED / NAME / "cell.yaml"))
    kinematics = world.kinematics  # built, as planning has built it before on_error
    assert [p.name for p in world.waiting_parts] == ["part:part"]
    lost = world.without_waiting("part")
    assert lost.waiting_parts == [] and lost.gone == {"part"}
    assert lost.kinematics is kinematics  # the arm's model is shared
    assert world.without_waiting("part") is lost  # built once
    assert lost.without_waiting("part") is lost and world.without_waiting("nothing") is world
