"""JSON Schema of cell and task files, for editors (VS Code YAML, etc.).

Every key has a description and an example: a field's docstring in the model is its
description, and its closing ``Example: `YAML` `` becomes the schema's ``examples``
(what an editor offers on completion). Steps are keyed by their kind (``{KIND: ARGS}``),
so an editor checks ARGS against that kind alone and names it in its message.
"""

from __future__ import annotations

import ast
import functools
import inspect
import json
import re
import sys
from typing import Any

from pydantic import BaseModel, TypeAdapter
from pydantic.json_schema import GenerateJsonSchema, JsonSchemaValue
from pydantic_core import core_schema

from cellrunner.model.cell import Cell
from cellrunner.model.task import STEP_MODELS, TOP_LEVEL_ONLY, Target, TaskFile
from cellrunner.model.units import NonNegativeLength, PositiveLength

#: a JSON Schema document (or part of one)
JsonDict = dict[str, Any]

_SHORT_FORMS: dict[str, Any] = {
    "move": Target,
    "approach": str,
    "descend": str,
    "linear": str,
    "lift": PositiveLength,
    "retreat": PositiveLength,
    "wait": float,
    "change_tool": str,
}
_BARE = ("grip", "release")


#: what each step kind does and an example of its arguments (hover text and completion)
STEP_HELP: dict[str, tuple[str, Any]] = {
    "move": (
        "Planned, collision-free joint move to a frame, 'home' or six joint angles (deg); "
        "or {to, offset, speed (fraction of the limits)}.",
        "home",
    ),
    "approach": (
        "Planned move to `distance` back from a frame along its Z.",
        {"to": "infeed", "distance": 0.1},
    ),
    "descend": ("Straight TCP line to a frame (speed in m/s).", "infeed"),
    "linear": (
        "Straight TCP line to a frame (speed in m/s).",
        {"to": "pallet", "offset": [0, 0, 0.02]},
    ),
    "lift": ("Straight line up world +Z by `distance` (m).", 0.1),
    "retreat": ("Straight line back along the tool's -Z by `distance` (m).", 0.05),
    "grip": (
        "Close the jaws, then check the confirmation input and the measured force window.",
        {"confirm": "gripper_closed", "force": {"min": 2, "max": 40}, "timeout": 1.5},
    ),
    "release": ("Open the jaws (optionally confirmed by an input).", {"timeout": 1.0}),
    "set_output": ("Set outputs by their cell IO names.", {"beacon": True}),
    "wait_input": (
        "Wait until an input reads `value`, failing the step after `timeout` (s).",
        {"input": "part_present", "value": True, "timeout": 10},
    ),
    "wait": ("Wait this long, s.", 0.5),
    "move_until_contact": (
        "Straight line along `direction` until the wrist force rises by `force` (N); "
        "fails without contact within `max_distance` (m).",
        {"direction": [0, 0, 1], "frame": "tool", "speed": 0.01, "force": 10, "max_distance": 0.05},
    ),
    "insert": (
        "Straight in to a frame and `depth` (m) past it under a force limit; ending outside "
        "`expect_depth` is a failed place (3).",
        {
            "to": "hole",
            "depth": 0.02,
            "speed": 0.005,
            "force": {"max": 20},
            "expect_depth": [0.018, 0.021],
        },
    ),
    "change_tool": (
        "Macro: park the mounted tool in its rack, take the named tool, switch TCP, "
        "payload and collision geometry.",
        "cup",
    ),
    "align": (
        "Look at an ArUco marker on the part at the next step's frame and correct the TCP "
        "until the marker is where that frame says; later steps aimed at the frame move "
        "with the correction; beyond `max_correction` the step fails (3).",
        {
            "camera": "wrist",
            "marker": {"dictionary": "DICT_4X4_50", "id": 7, "size": 0.03},
            "tolerance": {"xyz": 0.001, "rpy": 0.5},
            "max_correction": {"xyz": [0.015, 0.015, 0], "rpy": [0, 0, 8]},
            "attempts": 3,
        },
    ),
    "pick": (
        "Macro: approach -> descend -> grip -> lift.",
        {"at": "infeed", "approach": 0.1, "grip": {"confirm": "gripper_closed"}},
    ),
    "place": (
        "Macro: approach -> descend -> release -> retreat.",
        {
            "at": "pallet",
            "approach": 0.1,
            "pattern": {"grid": [3, 4], "pitch": [0.07, 0.07], "index": "slot"},
        },
    ),
}


def _steps_schema(defs: JsonDict, allow_macros: bool = True) -> JsonDict:
    """A list of steps: each a one-key mapping ``{KIND: ARGS}`` whose key names the step
    (the discriminator: an editor validates ARGS against that kind's schema alone and
    lists the known kinds for an unknown one), or a bare ``grip``/``release``."""
    kinds: dict[str, JsonDict] = {}
    for kind, model in STEP_MODELS.items():
        if not allow_macros and kind in TOP_LEVEL_ONLY:
            continue
        args = _json_schema(model | None if kind in _BARE else model, defs)
        if kind in _SHORT_FORMS:  # the mapping form, else the short form: errors name the one meant
            args = {
                "if": {"type": "object"},
                "then": args,
                "else": _json_schema(_SHORT_FORMS[kind], defs),
            }
        description, example = STEP_HELP.get(kind, ((model.__doc__ or kind).strip(), None))
        kinds[kind] = {
            **args,
            "title": kind,
            "description": description,
            **({"examples": [example]} if example is not None else {}),
        }
    step = {
        "type": "object",
        "title": "step",
        "description": "One step: {KIND: ARGS}.",
        "properties": kinds,
        "propertyNames": {"enum": list(kinds)},
        "additionalProperties": False,
        "minProperties": 1,
        "maxProperties": 1,
    }
    bare = {"type": "string", "enum": list(_BARE), "description": "A step without arguments."}
    return {"type": "array", "items": {"if": {"type": "string"}, "then": bare, "else": step}}


class _WithFieldDocstrings(GenerateJsonSchema):
    """Pydantic's schema with each field's docstring as its description, as
    ``use_attribute_docstrings`` would give; read here, when a schema is asked for, rather
    than at every model class's creation (that parse cost every command ~45 ms at start)."""

    def model_schema(self, schema: core_schema.ModelSchema) -> JsonSchemaValue:
        json_schema = super().model_schema(schema)
        cls = schema["cls"]
        properties = json_schema.get("properties", {})
        for name, field in cls.model_fields.items():
            doc = field_docstring(cls, name)
            key = field.alias if field.alias is not None else name
            if doc is not None and field.description is None and key in properties:
                properties[key]["description"] = doc
        return json_schema


def field_docstring(cls: type[BaseModel], name: str) -> str | None:
    """The docstring written under field ``name`` in ``cls`` or the first base that
    declares it (cleaned as ``inspect.cleandoc``), or None."""
    for base in cls.__mro__:
        if name in getattr(base, "__annotations__", {}):
            return _module_docstrings(base.__module__).get(base.__qualname__, {}).get(name)
    return None


@functools.cache
def _module_docstrings(module: str) -> dict[str, dict[str, str]]:
    """{class qualname: {field: docstring}} of the classes in ``module``'s source."""
    found: dict[str, dict[str, str]] = {}

    def visit(body: list[ast.stmt], prefix: str) -> None:
        for node in body:
            if not isinstance(node, ast.ClassDef):
                continue
            qualname = f"{prefix}{node.name}"
            docs = found.setdefault(qualname, {})
            for stmt, after in zip(node.body, [*node.body[1:], None], strict=True):
                if (
                    isinstance(stmt, ast.AnnAssign)
                    and isinstance(stmt.target, ast.Name)
                    and isinstance(after, ast.Expr)
                    and isinstance(after.value, ast.Constant)
                    and isinstance(after.value.value, str)
                ):
                    docs[stmt.target.id] = inspect.cleandoc(after.value.value)
            visit(node.body, f"{qualname}.")

    visit(ast.parse(inspect.getsource(sys.modules[module])).body, "")
    return found


def _json_schema(value_type: Any, defs: JsonDict) -> JsonDict:
    schema: JsonDict = _offset_short_form(
        _with_examples(TypeAdapter(value_type).json_schema(schema_generator=_WithFieldDocstrings))
    )
    defs.update(schema.pop("$defs", {}))
    return schema


#: yaml-language-server (VS Code YAML) validates draft-07; our schemas use nothing newer
DRAFT = "http://json-schema.org/draft-07/schema#"


def _with_examples(node: Any) -> Any:
    """Move each description's closing ``Example: `YAML` `` into ``examples``."""
    if isinstance(node, list):
        return [_with_examples(v) for v in node]
    if not isinstance(node, dict):
        return node
    out = {k: _with_examples(v) for k, v in node.items()}
    text = out.get("description")
    if isinstance(text, str) and (m := _EXAMPLE.search(text)):
        from ruamel.yaml import YAML

        out["description"] = text[: m.start()].rstrip()
        example = YAML(typ="safe", pure=True).load(m.group(1))
        out["examples"] = [
            json.loads(json.dumps(example))
        ]  # as a JSON file holds it (keys are strings)
    return out


def _offset_short_form(node: Any) -> Any:
    """``offset: [dx, dy, dz]`` is accepted (widened by the model's validator): say so."""
    if isinstance(node, list):
        return [_offset_short_form(v) for v in node]
    if not isinstance(node, dict):
        return node
    out = {k: _offset_short_form(v) for k, v in node.items()}
    if {"$ref": "#/$defs/Offset"} in out.get("anyOf", []):
        out["anyOf"] = [
            *out["anyOf"],
            {
                "type": "array",
                "minItems": 3,
                "maxItems": 3,
                "items": {"type": ["number", "string"]},
            },
        ]
    return out


_EXAMPLE = re.compile(r"\s*Example: `([^`]+)`\s*$")


def cell_schema() -> JsonDict:
    schema: JsonDict = _with_examples(Cell.model_json_schema(schema_generator=_WithFieldDocstrings))
    schema["$schema"] = DRAFT
    schema["title"] = "cellrunner cell file"
    return schema


def task_schema() -> JsonDict:
    schema: JsonDict = _offset_short_form(
        _with_examples(TaskFile.model_json_schema(schema_generator=_WithFieldDocstrings))
    )
    defs = schema.setdefault("$defs", {})
    steps = schema["properties"]["steps"]
    schema["properties"]["steps"] = {
        **_steps_schema(defs),
        "minItems": 1,
        "title": "Steps",
        "description": steps.get("description", "The steps, in order."),
        **({"examples": steps["examples"]} if "examples" in steps else {}),
    }
    between = defs["Retry"]["properties"]["between"]  # retry.between holds primitive steps
    defs["Retry"]["properties"]["between"] = {
        **_steps_schema(defs, allow_macros=False),
        "title": "Between",
        **{k: between[k] for k in ("description", "examples") if k in between},
    }
    schema["$schema"] = DRAFT
    schema["title"] = "cellrunner task file"
    return schema


__all__ = ["NonNegativeLength", "cell_schema", "task_schema"]
