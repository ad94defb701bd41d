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
        assert published == schema, (
            f"schema/{kind}.schema.json is stale: run cellrunner schema --write schema"
        )


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


def _properties(node, path=""):
    """(path, property schema) of every key of every object in a schema."""
    if isinstance(node, dict):
        props = node.get("properties")
        if isinstance(props, dict) and node.get("type") == "object":
            for key, sub in props.items():
                yield f"{path}/{key}", sub
        for key, sub in node.items():
            yield from _properties(sub, f"{path}/{key}")
    elif isinstance(node, list):
        for i, sub in enumerate(node):
            yield from _properties(sub, f"{path}/{i}")


def test_every_key_has_a_description_and_an_example_that_validates():
    for schema in (cell_schema(), task_schema()):
        props = list(_properties(schema))
        assert len(props) > 60
        for path, sub in props:
            assert sub.get("description") and sub.get("examples"), (
                f"{path}: give the field a docstring ending in Example: `YAML` (a step kind: its summary "
                "and example in cellrunner/steps/KIND.py)"
            )
            assert "Example:" not in sub["description"], path
            check = jsonschema.Draft7Validator({**sub, "$defs": schema.get("$defs", {})})
            for example in sub["examples"]:
                assert check.is_valid(example), f"{path}: example {example!r} fails its own schema"


def _first_error(schema, instance):
    return jsonschema.exceptions.best_match(
        jsonschema.Draft7Validator(schema).iter_errors(instance)
    )


def test_step_kinds_discriminate_so_errors_name_the_step():
    schema = task_schema()
    error = _first_error(
        schema, {"task": "t", "steps": [{"move": "home"}, {"move": {"to": "home", "sped": 1}}]}
    )
    assert list(error.absolute_path) == ["steps", 1, "move"]
    assert error.message == "Additional properties are not allowed ('sped' was unexpected)"
    error = _first_error(
        schema, {"task": "t", "steps": [{"pick": {"at": "infeed", "grip": {"timeout": [1]}}}]}
    )
    assert list(error.absolute_path)[:4] == ["steps", 0, "pick", "grip"]
    error = _first_error(schema, {"task": "t", "steps": [{"mvoe": "home"}]})
    assert error.message.startswith("'mvoe' is not one of ['move', 'approach', 'descend', 'linear'")
    error = _first_error(schema, {"task": "t", "steps": ["gripp"]})
    assert error.message == "'gripp' is not one of ['grip', 'release', 'untrack']"
    error = _first_error(schema, {"task": "t", "steps": [{"move": "home", "wait": 1}]})
    assert "has too many properties" in error.message  # one step per list item
    between = _first_error(
        schema,
        {
            "task": "t",
            "steps": [{"pick": {"at": "a", "retry": {"between": [{"pick": {"at": "a"}}]}}}],
        },
    )
    assert "'pick'" in between.message and "between" in list(
        between.absolute_path
    )  # no macros between retries
    assert schema["properties"]["steps"]["items"]["else"]["properties"]["pick"][
        "description"
    ].startswith("Macro:")


def test_schema_is_what_yaml_language_server_reads():
    """yaml-language-server (VS Code YAML) validates draft-07 schemas: declare it, and use
    no keyword from later drafts; step kinds are property names an editor completes."""
    newer = {
        "prefixItems",
        "$dynamicRef",
        "$dynamicAnchor",
        "unevaluatedProperties",
        "unevaluatedItems",
        "dependentSchemas",
        "dependentRequired",
        "$recursiveRef",
        "$anchor",
    }
    for schema in (cell_schema(), task_schema()):
        assert schema["$schema"] == "http://json-schema.org/draft-07/schema#"
        jsonschema.Draft7Validator.check_schema(schema)
        text = json.dumps(schema)
        assert not {k for k in newer if f'"{k}"' in text}
    kinds = task_schema()["properties"]["steps"]["items"]["else"]["propertyNames"]["enum"]
    assert {"move", "approach", "pick", "place", "wait_input"} <= set(kinds)
