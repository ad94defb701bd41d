"""Tight fits (SPEC section 12): ``contact: [FIXTURE, ...]`` and ``clearance:`` on
``descend`` and ``insert`` let a 20 mm peg into a hole whose walls are 2 mm or 0.5 mm
away; without them check refuses the line and its hint names both."""

from __future__ import annotations

import contextlib
import io

import pytest

from cellrunner.cli.main import main
from tests.planning.tight_peg import WALLS, write
from tests.rig import json_of

CONTACT = f", contact: [{', '.join(WALLS)}]"


@pytest.mark.parametrize("gap_m", [0.002, 0.0005])
def test_walls_named_in_contact_let_the_peg_in(tmp_path, gap_m):
    out = json_of("check", *write(tmp_path, gap_m, CONTACT, CONTACT), "--no-cache")
    assert out["ok"], out["errors"]
    insert = next(s for s in out["steps"] if s["kind"] == "insert")
    assert "wall_xm" in insert["message"]  # the contact allowed, as the row says


def test_a_step_clearance_lets_the_peg_in_without_naming_walls(tmp_path):
    clearance = ", clearance: 0.0015"
    assert json_of("check", *write(tmp_path, 0.002, clearance, clearance), "--no-cache")["ok"]


def test_without_contact_the_descend_is_refused_and_the_hint_names_contact(tmp_path):
    out = json_of("check", *write(tmp_path, 0.002), "--no-cache")
    assert not out["ok"]
    (error,) = out["errors"]
    assert error.startswith("step 7 descend 'hole': part 'peg' is too close to fixture 'wall_")
    assert "move the frame or fixture" not in error
    assert f"name them in the step's contact: [{', '.join(WALLS)}]" in error
    assert "or give the step clearance: 0.0018" in error


def test_only_the_named_walls_may_be_touched(tmp_path):
    """Naming three walls of four leaves the fourth at the full clearance."""
    three = f", contact: [{', '.join(WALLS[:3])}]"
    out = json_of("check", *write(tmp_path, 0.002, three, three), "--no-cache")
    assert not out["ok"]
    assert "fixture 'wall_yp'" in out["errors"][0]


def test_a_contact_naming_no_fixture_is_a_located_error(tmp_path):
    cell, task = write(tmp_path, 0.002, ", contact: [wal_xm]")
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        assert main(["validate", cell, task]) == 2
    text = err.getvalue()
    assert "unknown fixture 'wal_xm'" in text and "wall_xm" in text, text
    assert "task.yaml:6:" in text, text
