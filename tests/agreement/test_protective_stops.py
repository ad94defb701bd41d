"""Jaw jobs check approved and the twin stopped (issue 33), as bench/cellgen.py generated
them when they stopped:

- s208, a UR10e on the ceiling: the arm's shoulder could not brake at the controller's
  40 rad/s^2, overshot the pick's descend by 15-19 mm and put the open pads into the
  infeed table (100, protective stop). check now times every motion within the joints'
  torques (planning/dynamics.py).
- s80544, a UR10 on a wall placing a 1 kg part flush on its table: the twin's jaw weld
  let go whenever a finger lost the part's face for a period as the tool accelerated, and
  was made again where the part had sagged; it crept 1 mm down the pads over the carry and
  was pressed 1 mm into the table (172 N). A welded part stays welded while it touches a
  pad (sim/jaw_welds.py).
- s90344, a UR16e on a wall aligning on a part 2.4 mm and 1.35 deg off its frame: check
  left a part off its frame out of its obstacles (it lies where the camera finds it), and
  the move to the look pose swept the forearm through it (311 N). It is an obstacle
  within the align's max_correction of its frame (planning/placed.py found_parts)."""

from __future__ import annotations

from tests.agreement.generated import approved_and_rehearsed, copied


def test_a_ur10e_jaw_pick_check_approves_is_rehearsed_without_a_stop(tmp_path):
    checked, run = approved_and_rehearsed(*copied("s208-ur10e", tmp_path))
    # the shoulder follows its set-points: it overshot 15 mm at the descend's end before
    assert run["max_tracking_error_m"] < 0.005
    assert abs(run["cycle_time_s"] - checked["cycle_time_s"]) < 0.3


def test_a_part_gripped_at_its_centre_is_placed_flush_on_its_table_without_a_stop(tmp_path):
    approved_and_rehearsed(*copied("s80544-ur10-aligned", tmp_path))


def test_a_part_an_align_finds_off_its_frame_is_an_obstacle_to_the_moves_before(tmp_path):
    approved_and_rehearsed(*copied("s90344-ur16e-aligned", tmp_path))
