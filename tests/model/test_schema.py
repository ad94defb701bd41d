"""The published JSON Schema accepts valid files and matches `cellrunner schema`."""

import json

import jsonschema
from ruamel.yaml import YAML

from cellrunner.model.schema import cell_schema, task_schema
from tests.conftest import DEMO_CELL, ROOT

yaml = YAML(typ="safe", pure=True)

OTHER_CELL = """
cell: line3-cell2
robot:
  model: ur10e
  host: 192.168.1.101
  mount: {xyz: [0, 0, 0.90], rpy: [0, 0, 0]}
  home: [0, -90, 90, -90, -90, 0]
  limits: {joint_speed: [100, 100, 150, 150, 150, 150], joint_accel: 300, tcp_speed: "800 mm/s", margin: 0.9}
tool:
  tcp: {xyz: [0, 0, 0.2], rpy: [0, 0, 0]}
  gripper: {kind: robotiq, stroke: 0.085}
  geometry: [{sphere: {radius: 0.05}, xyz: [0, 0, 0.05]}]
fixtures:
  - {name: fence, mesh: {file: meshes/fence.stl}, pose: {xyz: [0, 0.6, 0.9]}}
frames:
  infeed: {xyz: [0.45, -0.35, 0.93], rpy: [180, 0, 0]}
tasks: {1: tasks/pick_place.yaml}
plc:
  modbus: {bind: 127.0.0.1, port: 502, heartbeat_timeout: 1.5}
  opcua: {endpoint: "opc.tcp://127.0.0.1:4840/cellrunner", security: [none], users: secrets/u.yaml}
journal: var/jobs.sqlite
"""


def test_published_schema_is_current():
    for kind, schema in (("cell", cell_schema()), ("task", task_schema())):
        published = json.loads((ROOT / "schema" / f"{kind}.schema.json").read_text())
        assert published == schema, f"schema/{kind}.schema.json is stale: run cellrunner schema --write schema"


def test_schema_accepts_valid_files():
    jsonschema.validate(yaml.load(DEMO_CELL.read_text()), cell_schema())
    jsonschema.validate(yaml.load(OTHER_CELL), cell_schema())
    for task in (ROOT / "tasks").glob("*.yaml"):
        jsonschema.validate(yaml.load(task.read_text()), task_schema())


def test_schema_refuses_unknown_keys_and_models():
    bad = yaml.load(OTHER_CELL)
    bad["robot"]["model"] = "ur6e"
    assert not jsonschema.Draft202012Validator(cell_schema()).is_valid(bad)
    bad = yaml.load(OTHER_CELL)
    bad["robot"]["hom"] = [0] * 6
    assert not jsonschema.Draft202012Validator(cell_schema()).is_valid(bad)
    task = {"task": "t", "steps": [{"mvoe": "home"}]}
    assert not jsonschema.Draft202012Validator(task_schema()).is_valid(task)
    task = {"task": "t", "steps": ["release", {"move": "home"}, {"wait": 1}, {"pick": {"at": "x"}}]}
    jsonschema.validate(task, task_schema())
