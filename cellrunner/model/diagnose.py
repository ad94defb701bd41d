"""Turning pydantic validation errors into located, readable diagnostics."""

from __future__ import annotations

import difflib
import types
import typing
from collections.abc import Iterable
from typing import Any

from pydantic import BaseModel, ValidationError
from pydantic_core import ErrorDetails

from cellrunner.errors import Diagnostic
from cellrunner.model.source import PathKey, Source


def dotted(path: PathKey) -> str:
    """``("steps", 3, "move", "to")`` -> ``steps[3].move.to`` (1-based list indices for
    steps are shown by the callers that know them)."""
    out = ""
    for part in path:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def did_you_mean(word: object, known: Iterable[object]) -> str:
    close = difflib.get_close_matches(str(word), [str(k) for k in known], n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def known_list(known: Iterable[object]) -> str:
    return ", ".join(str(k) for k in known) or "(none)"


def _unwrap(tp: Any) -> list[Any]:
    """The concrete candidate types inside Annotated/Optional/Union."""
    origin = typing.get_origin(tp)
    if origin is typing.Annotated:
        return _unwrap(typing.get_args(tp)[0])
    if origin in (typing.Union, types.UnionType):
        return [c for arg in typing.get_args(tp) for c in _unwrap(arg)]
    return [tp]


def fields_at(root: type[BaseModel], loc: PathKey) -> list[str] | None:
    """The field names of the model reached by ``loc`` from ``root``, if any."""
    candidates: list[Any] = [root]
    for part in loc:
        nxt: list[Any] = []
        for tp in candidates:
            for c in _unwrap(tp):
                origin = typing.get_origin(c)
                if isinstance(c, type) and issubclass(c, BaseModel):
                    if isinstance(part, str) and part in c.model_fields:
                        nxt.append(c.model_fields[part].annotation)
                elif origin in (list, tuple) and isinstance(part, int):
                    nxt.extend(typing.get_args(c)[:1])
                elif origin is dict:
                    nxt.append(typing.get_args(c)[1])
        if not nxt:
            return None
        candidates = nxt
    for tp in candidates:
        for c in _unwrap(tp):
            if isinstance(c, type) and issubclass(c, BaseModel):
                return list(c.model_fields)
    return None


def _describe(value: Any) -> str:
    if value is None:
        return "nothing (an empty value)"
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return "a list"
    return repr(value)


def message_of(error: ErrorDetails, root: type[BaseModel]) -> tuple[str, bool, PathKey]:
    """(message, point-at-key, loc to point at) for one pydantic error."""
    kind, loc, value = error["type"], tuple(error["loc"]), error.get("input")
    ctx = error.get("ctx") or {}
    if kind == "missing":
        return f"missing required key {loc[-1]!r}", True, loc[:-1]
    if kind == "extra_forbidden":
        known = fields_at(root, loc[:-1]) or []
        return (
            f"unknown key {loc[-1]!r}{did_you_mean(loc[-1], known)}; known: {known_list(known)}",
            True,
            loc,
        )
    if kind == "literal_error":
        expected = str(ctx.get("expected", "")).replace("'", "").replace(" or ", ", ")
        what = "robot model" if loc and loc[-1] == "model" else "value"
        words = [w.strip() for w in expected.split(",")]
        return (
            f"unknown {what} {value!r}{did_you_mean(value, words)}; known: {expected}",
            False,
            loc,
        )
    if kind == "string_pattern_mismatch":
        return (
            f"bad name {value!r}: names use letters, digits, '_' and '-', starting with a "
            "letter or '_'",
            False,
            loc,
        )
    if kind in ("model_type", "model_attributes_type", "dict_type"):
        return f"expected a mapping of keys, got {_describe(value)}", False, loc
    if kind in ("list_type", "tuple_type"):
        return f"expected a list, got {_describe(value)}", False, loc
    if kind in ("too_short", "too_long"):
        want = ctx.get("min_length") if kind == "too_short" else ctx.get("max_length")
        got = ctx.get("actual_length")
        field = ctx.get("field_type", "List").lower()
        return (
            f"expected {'at least' if kind == 'too_short' else 'at most'} {want} items in this {field}, got {got}",
            False,
            loc,
        )
    if kind in ("string_type",):
        return f"expected text, got {_describe(value)}", False, loc
    if kind in ("bool_type", "bool_parsing"):
        return f"expected true or false, got {_describe(value)}", False, loc
    if kind in ("int_type", "int_parsing", "int_from_float"):
        return f"expected a whole number, got {_describe(value)}", False, loc
    if kind in ("float_type", "float_parsing"):
        return f"expected a number, got {_describe(value)}", False, loc
    if kind in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
        word = {
            "greater_than": ">",
            "greater_than_equal": ">=",
            "less_than": "<",
            "less_than_equal": "<=",
        }[kind]
        bound = next(iter(ctx.values()), "?")
        bound = f"{bound:g}" if isinstance(bound, (int, float)) else bound
        return f"must be {word} {bound}, got {_describe(value)}", False, loc
    msg = error["msg"]
    for prefix in ("Value error, ", "Assertion failed, "):
        msg = msg.removeprefix(prefix)
    return msg, False, loc


def diagnostics_of(
    exc: ValidationError, source: Source, root: type[BaseModel], prefix: PathKey = ()
) -> list[Diagnostic]:
    """Located diagnostics for every error of ``exc``; ``prefix`` is where the validated
    data sits in the file."""
    out = []
    seen = set()
    for error in exc.errors(include_url=False):
        message, at_key, loc = message_of(error, root)
        where = dotted(_clean(prefix + loc))
        text = f"{where}: {message}" if where else message
        diag = source.diagnostic(prefix + loc, text, at_key=at_key)
        if (diag.line, diag.col, diag.message) not in seen:
            seen.add((diag.line, diag.col, diag.message))
            out.append(diag)
    return sorted(out, key=lambda d: (d.line, d.col))


def _clean(loc: PathKey) -> PathKey:
    """Drop pydantic's internal loc parts (union member names, '[key]')."""
    return tuple(
        p for p in loc if isinstance(p, int) or ("[" not in str(p) and "function-" not in str(p))
    )


def unknown_name(what: str, name: Any, known: Iterable[object]) -> str:
    """``unknown frame 'x' (did you mean 'y'?); known: ...``"""
    known = list(known)
    return f"unknown {what} {name!r}{did_you_mean(name, known)}; known: {known_list(known)}"
