"""JSON Schema of cell and task files, for editors (VS Code YAML, etc.)."""

from __future__ import annotations

from typing import Any, Literal, Optional, Union

from pydantic import TypeAdapter, create_model

from cellrunner.model.base import Strict
from cellrunner.model.cell import Cell
from cellrunner.model.task import STEP_MODELS, Target, TaskFile
from cellrunner.model.units import NonNegativeLength, PositiveLength

_SHORT_FORMS: dict[str, Any] = {
    "move": Target,
    "approach": str,
    "descend": str,
    "linear": str,
    "lift": PositiveLength,
    "retreat": PositiveLength,
    "wait": float,
}
_BARE = ("grip", "release")


def _step_schema_type(allow_macros: bool = True):
    members = []
    for kind, model in STEP_MODELS.items():
        if not allow_macros and kind in ("pick", "place"):
            continue
        value_type: Any = model
        if kind in _SHORT_FORMS:
            value_type = Union[model, _SHORT_FORMS[kind]]
        if kind in _BARE:
            value_type = Optional[model]
        wrapper = create_model(f"{kind.title().replace('_', '')}Step", __base__=Strict,
                               **{kind: (value_type, ...)})
        members.append(wrapper)
    members.append(Literal[_BARE])  # type: ignore[valid-type]
    return Union[tuple(members)]  # type: ignore[return-value]


def cell_schema() -> dict:
    schema = Cell.model_json_schema()
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    schema["title"] = "cellrunner cell file"
    return schema


def task_schema() -> dict:
    schema = TaskFile.model_json_schema()
    steps = TypeAdapter(list[_step_schema_type()]).json_schema()
    defs = schema.setdefault("$defs", {})
    defs.update(steps.pop("$defs", {}))
    schema["properties"]["steps"] = {**steps, "minItems": 1, "title": "Steps"}
    # retry.between holds primitive steps
    primitive = TypeAdapter(list[_step_schema_type(allow_macros=False)]).json_schema()
    defs.update(primitive.pop("$defs", {}))
    defs["Retry"]["properties"]["between"] = {**primitive, "title": "Between"}
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    schema["title"] = "cellrunner task file"
    return schema


__all__ = ["cell_schema", "task_schema", "NonNegativeLength"]
