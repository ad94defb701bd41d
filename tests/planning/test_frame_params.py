"""Frame-valued params (issue 24): ``type: frame`` with ``choices`` names one of the cell's
frames wherever a frame is read (the left or the right pallet); check proves every choice;
Modbus sends the choice's index, OPC UA and the CLI its name."""

from __future__ import annotations

import contextlib
import io

import pytest

from cellrunner.cli.main import main
from cellrunner.model.params import Param
from cellrunner.plc.param_registers import decode_params
from tests.conftest import DEMO_CELL
from tests.rig import json_of

TASK = """task: side
params:
  side: {type: frame, choices: CHOICES}
steps:
  - move: home
  - pick: {at: infeed}
  - place: {at: side}
  - move: home
"""


@pytest.fixture
def cell(tmp_path):
    """The demo cell with a second pallet beside the first, and one off the table."""
    path = tmp_path / "cell.yaml"
    text = DEMO_CELL.read_text()
    line = next(ln for ln in text.splitlines() if ln.lstrip().startswith("pallet: {xyz:"))
    extra = (
        "\n  left: {xyz: [0.30, 0.30, 0.928], rpy: [180, 0, 90]}"
        "\n  off_table: {xyz: [0.30, 0.80, 0.928], rpy: [180, 0, 90]}"
    )
    path.write_text(text.replace(line, line + extra))
    return path


def write(tmp_path, choices: str):
    task = tmp_path / "t.yaml"
    task.write_text(TASK.replace("CHOICES", choices))
    return str(task)


def test_every_choice_is_proved(tmp_path, cell):
    out = json_of("check", str(cell), write(tmp_path, "[pallet, left]"), "--no-cache")
    assert out["ok"], out["errors"]
    assert out["params"] == {"side": "pallet"}  # the first choice by default
    assert out["slots_checked"] == {"side": ["pallet", "left"]}
    places = [s["name"] for s in out["steps"] if s["kind"] == "descend"]
    assert places[-1] == "pallet"
    out = json_of(
        "check", str(cell), write(tmp_path, "[pallet, left]"), "-p", "side=left", "--no-cache"
    )
    assert out["ok"] and [s["name"] for s in out["steps"] if s["kind"] == "descend"][-1] == "left"


def test_a_choice_that_fails_is_named(tmp_path, cell):
    out = json_of("check", str(cell), write(tmp_path, "[pallet, off_table]"), "--no-cache")
    assert not out["ok"]
    assert out["errors"][0].startswith(
        "side=off_table: step 8 release 'off_table': the part 'block' would be let go with "
        "nothing under it"
    )


def test_a_choice_that_is_no_frame_is_a_located_error(tmp_path, cell):
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        assert main(["validate", str(cell), write(tmp_path, "[pallet, lefty]")]) == 2
    assert "t.yaml:3:" in err.getvalue()
    assert "params.side.choices[1]: unknown frame 'lefty'" in err.getvalue()


def test_modbus_sends_the_index_and_opc_ua_the_name():
    param = Param(type="frame", choices=["pallet", "left"])
    (value,) = decode_params([("side", "frame", None)], [1]).values()
    assert param.coerce("side", value) == "left"  # Modbus: register word 1
    assert param.coerce("side", "pallet") == "pallet"  # OPC UA, CLI
    with pytest.raises(
        ValueError, match=r"must be one of pallet, left \(or its index 0-1\), got 2"
    ):
        param.coerce("side", 2)
