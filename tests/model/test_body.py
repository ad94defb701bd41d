"""Bodies named in collision pairs and blockers: data whose text is today's message text."""

from __future__ import annotations

import json
import pickle

import pytest

from cellrunner.model.body import Body, BodyKind


@pytest.mark.parametrize(
    ("body", "text"),
    [
        (Body(BodyKind.ROBOT_LINK, "upper_arm"), "upper_arm"),
        (Body(BodyKind.TOOL, "gripper"), "tool 'gripper'"),
        (Body(BodyKind.PART, "block"), "part 'block'"),
        (Body(BodyKind.FIXTURE, "table"), "fixture 'table'"),
        (Body(BodyKind.WAITING_PART, "block"), "waiting part 'block'"),
    ],
)
def test_a_body_reads_as_the_messages_name_it(body: Body, text: str) -> None:
    assert body == text and str(body) == text and f"{body}" == text


def test_a_scene_fixture_name_gives_its_kind_and_back() -> None:
    waiting = Body.fixture("part:block")
    assert (waiting.kind, waiting.name, waiting.fixture_name) == (
        BodyKind.WAITING_PART,
        "block",
        "part:block",
    )
    table = Body.fixture("table")
    assert (table.kind, table.name, table.fixture_name) == (BodyKind.FIXTURE, "table", "table")
    assert waiting.is_obstacle and table.is_obstacle
    assert not Body(BodyKind.TOOL, "gripper").is_obstacle
    assert Body(BodyKind.ROBOT_LINK, "forearm").fixture_name == ""


def test_a_body_survives_pickling_and_json() -> None:
    body = Body(BodyKind.WAITING_PART, "block")
    back = pickle.loads(pickle.dumps(body))
    assert (back.kind, back.name, str(back)) == (body.kind, body.name, str(body))
    assert json.loads(json.dumps([body])) == ["waiting part 'block'"]
