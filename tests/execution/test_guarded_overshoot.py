"""A guarded line's force stays near its limit: after the contact the arm goes back along
the line with its speeds pointing back (streamed as the approved set-points backwards,
:func:`cellrunner.model.trajectory.backwards`). Streamed with the line's own forward
speeds, the twin's servo feed-forward drove the finger into the block on the first
set-point back: 38 N against a 15 N limit (the issue's 40-60 N); now the peak is the
contact's own rise until the stop (~25 N at 10 mm/s onto steel-stiff contact)."""

from __future__ import annotations

import numpy as np
import pytest

from cellrunner.backends.sim.backend import SimBackend
from cellrunner.errors import InternalError
from cellrunner.model.codes import ResultCode
from cellrunner.model.load import load_cell, load_task
from cellrunner.model.trajectory import Trajectory, approve, backwards
from cellrunner.sim.from_cell import description_of
from tests.cells.reference import probe_task
from tests.conftest import ROOT
from tests.execution.twin_cell import twin_cell

PROBE_STEP = 3


def test_backwards_is_the_approved_set_points_in_reverse_and_stays_approved():
    q = np.linspace(0.0, 0.1, 11)[:, None] * np.ones(6)
    approved = approve(Trajectory(500.0, np.arange(11) / 500.0, q), 3, "line")
    back = backwards(approved, 8, 2)
    assert back.is_sealed and (back.step_index, back.step_name) == (3, "line")
    np.testing.assert_array_equal(back.trajectory.q_rad, q[2:9][::-1])
    assert (back.trajectory.qd_rad_s < 0).all()  # its speeds point back along the line
    with pytest.raises(InternalError, match=r"outside 0\.\.10"):
        backwards(approved, 11, 2)


def test_a_guarded_line_onto_a_block_peaks_under_twice_its_limit(tmp_path):
    text = (ROOT / "cells" / "peg_ur3e.yaml").read_text()
    (tmp_path / "cell.yaml").write_text(text.replace("tasks: {1: tasks/peg_insert.yaml}", ""))
    cell = load_cell(tmp_path / "cell.yaml")
    (tmp_path / "probe.yaml").write_text(probe_task(0.1, force_N=15.0))
    backend = SimBackend(description_of(cell))
    controller, loop = twin_cell(cell, {1: load_task(tmp_path / "probe.yaml", cell)}, backend)
    assert controller.start_job(1, {}, "probe", "cli").accepted
    for _ in range(60_000):
        loop.step()
        if controller.status().last_result is not None:
            break
    result = controller.status().last_result
    trace = controller.last_runner.ctx.notes["force_trace"]
    controller.close()
    assert result.result_code == ResultCode.OK, result.result_text
    peak_N = max(f for _, step, f in trace if step == PROBE_STEP)
    assert 15.0 < peak_N < 30.0
