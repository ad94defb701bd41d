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
from cellrunner.model.step_kinds import STEP_KINDS
from cellrunner.model.task import TaskFile
from cellrunner.model.units import NonNegativeLength

#: a JSON Schema document (or part of one)
JsonDict = dict[str, Any]


def _steps_schema(defs: JsonDict, allow_macros: bool = True) -> JsonDict:
    """A list of steps: each a one-key mapping ``{KIND: ARGS}`` whose key names the step
    (the discriminator: an editor validates ARGS against that kind's schema alone and
    lists the known kinds for an unknown one), or a bare ``grip``/``release``."""
    kinds: dict[str, JsonDict] = {}
    for kind in (STEP_KINDS[name] for name in STEP_KINDS.written()):
        if not allow_macros and kind.top_level_only:
            continue
        model = kind.args
        assert model is not None  # written() holds the kinds with a model
        args = _json_schema(model | None if kind.bare else model, defs)
        # the mapping form, else the short form: errors name the one meant
        if kind.short_schema is not None:
            args = {
                "if": {"type": "object"},
                "then": args,
                "else": _json_schema(kind.short_schema, defs),
            }
        description = kind.summary or (model.__doc__ or kind.name).strip()
        example = kind.example
        kinds[kind.name] = {
            **args,
            "title": kind.name,
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
    bare_kinds = [name for name in STEP_KINDS.written() if STEP_KINDS[name].bare]
    bare = {"type": "string", "enum": bare_kinds, "description": "A step without arguments."}
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
