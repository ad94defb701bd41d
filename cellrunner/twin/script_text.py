"""The text of an uploaded URScript program: literal statements and ur_rtde's injected path.

The twin runs no URScript interpreter: it reads statements whose arguments are literals
(``name(args, k=v)``, poses ``p[...]`` as lists) and the movej/movel lines ur_rtde injects
after ``# inject move path``. Anything else is a :class:`ScriptError` naming the statement.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

INJECT_PATH = "# inject move path\n"


class ScriptError(ValueError):
    """A program the twin cannot run; the message names the offending statement."""


# --------------------------------------------------------------------------- literals


def _literal(node: ast.AST) -> Any:
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float, bool, str)):
        return node.value
    if isinstance(node, ast.List):
        return [_literal(e) for e in node.elts]
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        v = _literal(node.operand)
        return -v if isinstance(node.op, ast.USub) else v
    if isinstance(node, ast.BinOp) and isinstance(node.op, (ast.Add, ast.Sub, ast.Mult, ast.Div)):
        left, right = _literal(node.left), _literal(node.right)
        ops: dict[type, Callable[[Any, Any], Any]] = {
            ast.Add: lambda a, b: a + b,
            ast.Sub: lambda a, b: a - b,
            ast.Mult: lambda a, b: a * b,
            ast.Div: lambda a, b: a / b,
        }
        return ops[type(node.op)](left, right)
    raise ScriptError(f"not a literal: {ast.unparse(node)}")


def parse_call(line: str) -> tuple[str, list[Any], dict[str, Any]]:
    """``name(args, k=v)`` with literal arguments; URScript poses ``p[...]`` are lists."""
    source = re.sub(r"\bp\[", "[", line.strip())
    try:
        node = ast.parse(source, mode="eval").body
    except SyntaxError as exc:
        raise ScriptError(f"cannot parse: {line.strip()}") from exc
    if not isinstance(node, ast.Call) or not isinstance(node.func, ast.Name):
        raise ScriptError(f"unsupported statement: {line.strip()}")
    args = [_literal(a) for a in node.args]
    kwargs = {k.arg: _literal(k.value) for k in node.keywords if k.arg}
    if re.search(r"\(\s*p\[", line):
        kwargs["_pose"] = True  # the first argument was a pose p[...], not joint angles
    return node.func.id, args, kwargs


# --------------------------------------------------------------------------- paths


@dataclass(frozen=True)
class PathEntry:
    """One injected path line: ``movej``/``movel`` to joints or a pose, with a, v, r."""

    kind: str  # "movej" | "movel"
    target: tuple[float, ...]
    is_pose: bool
    a: float
    v: float
    r: float
    progress: int  # the signal_async_progress index that precedes it


def parse_move_path(text: str) -> list[PathEntry]:
    """The movej/movel lines ur_rtde injected after ``# inject move path``."""
    start = text.find(INJECT_PATH)
    if start < 0:
        return []
    entries: list[PathEntry] = []
    progress = 0
    for line in text[start + len(INJECT_PATH) :].splitlines():
        stripped = line.strip()
        if stripped == "end":
            break
        if not stripped or stripped.startswith(("#", "textmsg")):
            continue
        name, args, kwargs = parse_call(stripped)
        if name == "signal_async_progress":
            progress = int(args[0])
            continue
        if name not in ("movej", "movel", "movep"):
            raise ScriptError(f"unsupported path statement: {stripped}")
        is_pose = bool(re.search(r"\(\s*p\[", stripped))
        entries.append(
            PathEntry(
                "movej" if name == "movej" else "movel",
                tuple(float(x) for x in args[0]),
                is_pose,
                float(kwargs.get("a", 1.4 if name == "movej" else 1.2)),
                float(kwargs.get("v", 1.05 if name == "movej" else 0.25)),
                float(kwargs.get("r", 0.0)),
                progress,
            )
        )
    return entries
