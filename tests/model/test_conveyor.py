"""A cell's conveyors: valid files load, mistakes are located errors that name the valid
choices, and the belt's geometry (its shift, its velocity) agrees with itself."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cellrunner.errors import InputError
from cellrunner.model.codes import ResultCode
from cellrunner.model.conveyor import (
    ArcPath,
    ConveyorPath,
    LinePath,
    T_world_shift,
    belt_velocity_mps,
    s_of_point_m,
)
from cellrunner.model.load import load_cell
from tests.conftest import ROOT

REFERENCE = ROOT / "cells" / "conveyor_pick_ur10e.yaml"

CELL = """cell: c
robot: {model: ur10e, home: [0, -90, 90, -90, -90, 0]}
io: {inputs: {part_at_eye: DI0}, outputs: {jaws: DO0}}
frames:
  belt_pick: {xyz: [0.75, 0.0, 0.825], rpy: [180, 0, 0]}
conveyors:
  belt:
    path: PATH
    encoder: ENCODER
    trigger: {input: TRIGGER}
    eye_to_frame: EYE
    frame: FRAME
    window: WINDOW
    speed_max: 0.3
"""


def cell_text(**changes: str) -> str:
    values = {
        "PATH": "{line: {from: [0.75, -0.9, 0.8], to: [0.75, 0.9, 0.8]}}",
        "ENCODER": "{source: ur, index: 0, ticks_per_m: 4000}",
        "TRIGGER": "part_at_eye",
        "EYE": "0.5",
        "FRAME": "belt_pick",
        "WINDOW": "[-0.25, 0.4]",
    }
    values.update(changes)
    text = CELL
    for key, value in values.items():
        text = text.replace(key, value)
    return text


def errors_of(tmp_path: Path, text: str) -> list[str]:
    path = tmp_path / "c.yaml"
    path.write_text(text)
    with pytest.raises(InputError) as exc:
        load_cell(path)
    return [str(d) for d in exc.value.diagnostics]


def test_the_reference_conveyor_loads():
    cell = load_cell(REFERENCE).cell
    belt = cell.conveyors["belt"]
    assert belt.encoder.source == "ur" and belt.encoder.ticks_per_m == 4000
    assert belt.window == [-0.25, 0.4] and belt.speed_max == pytest.approx(0.3)
    assert belt.path.length_m == pytest.approx(1.8)


def test_units_and_the_other_encoders_load(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text(
        cell_text(ENCODER="{source: plc, register: 22, ticks_per_m: 1000}", EYE='"500 mm"')
    )
    belt = load_cell(path).cell.conveyors["belt"]
    assert belt.encoder.register_ == 22 and belt.eye_to_frame == pytest.approx(0.5)
    path.write_text(cell_text(ENCODER='{source: speed, mps: "250 mm/s"}'))
    assert load_cell(path).cell.conveyors["belt"].encoder.mps == pytest.approx(0.25)


@pytest.mark.parametrize(
    ("change", "line", "message"),
    [
        (
            {"FRAME": "belt_pik"},
            12,
            "conveyors.belt.frame: unknown frame 'belt_pik' (did you mean 'belt_pick'?); "
            "known: belt_pick",
        ),
        (
            {"TRIGGER": "part_at_ey"},
            10,
            "conveyors.belt.trigger.input: unknown input 'part_at_ey' (did you mean "
            "'part_at_eye'?); known: part_at_eye",
        ),
        (
            {"TRIGGER": "jaws"},
            10,
            "conveyors.belt.trigger.input: 'jaws' is an output, not an input; known inputs: "
            "part_at_eye",
        ),
        (
            {"PATH": "{line: {from: [0.9, -0.9, 0.8], to: [0.9, 0.9, 0.8]}}"},
            12,
            "conveyors.belt.frame: frame 'belt_pick' lies 150 mm off the conveyor's path "
            "(at most 20 mm): a part on the belt never reaches it",
        ),
        (
            {"EYE": "1.2"},
            11,
            "conveyors.belt.eye_to_frame: the eye 1.2 m before 'belt_pick' lies at -0.300 m "
            "along a path of 1.800 m",
        ),
        (
            {"WINDOW": "[-0.25, 1.2]"},
            13,
            "conveyors.belt.window: window [-0.25, 1.2] m about 'belt_pick' (at 0.900 m) runs "
            "off the path [0, 1.800] m; it may run [-0.900, 0.900]",
        ),
    ],
)
def test_references_are_located_errors(tmp_path, change, line, message):
    errors = errors_of(tmp_path, cell_text(**change))
    assert len(errors) == 1, errors
    where, _, text = errors[0].partition(" error: ")
    assert where.startswith(f"{tmp_path / 'c.yaml'}:{line}:")
    assert text == message


@pytest.mark.parametrize(
    ("change", "fragment"),
    [
        ({"ENCODER": "{source: ur}"}, "encoder source ur needs ticks_per_m"),
        (
            {"ENCODER": "{source: plc, register: 21, ticks_per_m: 1000}"},
            "register 21 is not one of 20, 22, 24, 26, 28",
        ),
        (
            {"ENCODER": "{source: speed, mps: 0.2, ticks_per_m: 10}"},
            "encoder source speed takes no ticks_per_m",
        ),
        (
            {"ENCODER": "{source: speed, mps: 0.4}"},
            "the belt runs at 0.4 m/s (encoder mps), above the speed_max 0.3 m/s",
        ),
        (
            {"WINDOW": "[0.4, -0.25]"},
            "window [0.4, -0.25] m must run from its start to a later end",
        ),
        (
            {
                "PATH": "{line: {from: [0, 0, 0], to: [1, 0, 0]}, arc: {centre: [0, 0, 0], radius: 1, from_deg: 0, to_deg: 90}}"
            },
            "a path needs exactly one of line, arc; got line, arc",
        ),
    ],
)
def test_bad_values_are_located_errors(tmp_path, change, fragment):
    errors = errors_of(tmp_path, cell_text(**change))
    assert len(errors) == 1, errors
    assert f"{tmp_path / 'c.yaml'}:" in errors[0] and fragment in errors[0]


def test_two_plc_encoders_on_one_register_pair_are_refused(tmp_path):
    text = cell_text(ENCODER="{source: plc, register: 20, ticks_per_m: 1000}")
    second = text[text.index("  belt:") :].replace("  belt:", "  belt2:", 1)
    errors = errors_of(tmp_path, text + second)
    assert any(
        "conveyors.belt2.encoder.register: registers 20-21 already carry conveyor 'belt''s" in e
        for e in errors
    ), errors


def test_a_feed_names_a_known_conveyor(tmp_path):
    text = cell_text() + (
        "parts: [{name: block, box: {size: [0.04, 0.04, 0.05]}, mass: 0.2, at: belt_pick}]\n"
        "sim: {feed: {part: block, conveyor: belts, every: 2.0, jitter: 0.01}}\n"
    )
    errors = errors_of(tmp_path, text)
    assert len(errors) == 1 and "sim.feed.conveyor: unknown conveyor 'belts'" in errors[0]
    (tmp_path / "ok.yaml").write_text(text.replace("belts", "belt"))
    feed = load_cell(tmp_path / "ok.yaml").cell.sim.feed
    assert feed.frame(load_cell(tmp_path / "ok.yaml").cell.conveyors) == "belt_pick"


def test_result_109_is_the_part_that_left_the_window():
    assert int(ResultCode.PART_LEFT_WINDOW) == 109
    assert ResultCode.PART_LEFT_WINDOW.text == "part left the conveyor window"
    assert ResultCode.PART_LEFT_WINDOW.is_fault


# ------------------------------------------------------------------ geometry

LINE = ConveyorPath(line=LinePath.model_validate({"from": [0.2, -0.5, 0.8], "to": [0.9, 0.4, 0.8]}))
ARC = ConveyorPath(arc=ArcPath(centre=[0.6, 0.1, 0.8], radius=0.4, from_deg=-120, to_deg=150))
distances = st.floats(-0.25, 1.5, allow_nan=False)  # along either path from 0.3 m


@pytest.mark.parametrize("path", [LINE, ARC], ids=["line", "arc"])
@settings(max_examples=40, deadline=None)
@given(a=distances, b=st.floats(-1.0, 1.0, allow_nan=False))
def test_shifts_compose_and_keep_parts_on_the_path(path, a, b):
    assert np.allclose(T_world_shift(path, a) @ T_world_shift(path, b), T_world_shift(path, a + b))
    start = np.array([*_point(path, 0.3), 1.0])
    moved = T_world_shift(path, a) @ start
    s, off = s_of_point_m(path, moved[:3])
    assert off == pytest.approx(0.0, abs=1e-9)
    assert s == pytest.approx(0.3 + a, abs=1e-9)


@pytest.mark.parametrize("path", [LINE, ARC], ids=["line", "arc"])
def test_belt_velocity_is_the_derivative_of_its_shift(path):
    p = np.array([*_point(path, 0.2), 1.0]) + np.array([0.01, -0.02, 0.05, 0.0])
    h, speed = 1e-6, 0.3
    numeric = (T_world_shift(path, speed * h) @ p - T_world_shift(path, -speed * h) @ p) / (2 * h)
    assert np.allclose(belt_velocity_mps(path, p[:3], speed), numeric[:3], atol=1e-6)


def _point(path: ConveyorPath, s_m: float) -> list[float]:
    if path.line is not None:
        a, b = np.array(path.line.from_), np.array(path.line.to)
        return list(a + (b - a) / np.linalg.norm(b - a) * s_m)
    arc = path.arc
    angle = math.radians(arc.from_deg) + s_m / arc.radius
    return [
        arc.centre[0] + arc.radius * math.cos(angle),
        arc.centre[1] + arc.radius * math.sin(angle),
        arc.centre[2],
    ]
