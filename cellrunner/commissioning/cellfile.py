"""Writing one pose into a cell file, leaving every other byte as it was.

The file is read with ruamel.yaml's round-trip loader only to locate the pose (line and
column of each node); the new value is spliced into the text there, so comments, key
order, flow or block style and spacing elsewhere stay byte for byte. The result is read
back and must carry exactly the new pose and nothing else changed, or nothing is written.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.errors import CellrunnerError

if TYPE_CHECKING:
    from ruamel.yaml.comments import CommentedMap

#: decimals written: 0.01 mm for xyz (m), 0.0001 deg for rpy
XYZ_DECIMALS, RPY_DECIMALS = 5, 4


class CellFileError(CellrunnerError):
    """The cell file cannot take the pose where it belongs (say where and why)."""

    exit_code = 2


@dataclass(frozen=True)
class PoseEdit:
    """The cell file before and after writing one pose, and the unified diff between."""

    path: Path
    before: str
    after: str

    @property
    def diff(self) -> str:
        return "".join(
            difflib.unified_diff(
                self.before.splitlines(True),
                self.after.splitlines(True),
                str(self.path),
                str(self.path),
            )
        )

    def apply(self) -> None:
        self.path.write_text(self.after)


def _number(value: float, decimals: int) -> str:
    text = f"{value:.{decimals}f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def _seq(values: Iterable[float], decimals: int) -> str:
    return "[" + ", ".join(_number(float(v), decimals) for v in values) + "]"


def pose_edit(
    path: Path,
    keys: tuple[str, ...],
    xyz_m: Iterable[float],
    rpy_deg: Iterable[float] | None = None,
) -> PoseEdit:
    """The cell file at ``path`` with the pose at ``keys`` (``("frames", "pick")``,
    ``("tool", "tcp")``) set to ``xyz_m`` and, unless None, ``rpy_deg``; a missing pose
    is added as the first entry of its parent mapping. Raises CellFileError when the
    parent is missing or written in a style this cannot edit safely."""
    text = path.read_text()
    lines = text.splitlines(True)
    values = {"xyz": _seq(xyz_m, XYZ_DECIMALS)}
    if rpy_deg is not None:
        values["rpy"] = _seq(rpy_deg, RPY_DECIMALS)
    root = _round_trip(text, path)
    parent = _mapping_at(root, keys[:-1], path)
    node = parent.get(keys[-1]) if parent is not None else None
    if node is None:
        after = _insert(text, lines, root, keys, values, path)
    else:
        after = _splice(text, lines, node, keys, values, path)
    _check(path, text, after, keys, values)
    return PoseEdit(path, text, after)


def _round_trip(text: str, path: Path) -> Any:  # ruamel's round-trip document
    from ruamel.yaml import YAML
    from ruamel.yaml.error import YAMLError

    try:
        return YAML(typ="rt").load(text)
    except YAMLError as exc:
        raise CellFileError(f"{path}: not valid YAML: {exc}") from None


def _mapping_at(root: Any, keys: tuple[str, ...], path: Path) -> CommentedMap | None:
    from ruamel.yaml.comments import CommentedMap

    node = root
    for key in keys:
        if not hasattr(node, "get") or node.get(key) is None:
            return None
        node = node[key]
    if not isinstance(node, CommentedMap):  # a mapping keeps its line and column (lc)
        raise CellFileError(f"{path}: {'.'.join(keys)} is not a mapping")
    return node


def _offset(lines: list[str], line: int, col: int) -> int:
    return sum(len(x) for x in lines[:line]) + col


def _flow_end(text: str, start: int, open_: str, close: str) -> int:
    """Index just past the bracket that closes the one at ``start``."""
    depth = 0
    for i in range(start, len(text)):
        if text[i] == open_:
            depth += 1
        elif text[i] == close:
            depth -= 1
            if depth == 0:
                return i + 1
    raise CellFileError("unbalanced brackets")


def _splice(
    text: str,
    lines: list[str],
    node: CommentedMap,
    keys: tuple[str, ...],
    values: dict[str, str],
    path: Path,
) -> str:
    """Replace the xyz/rpy values of an existing pose mapping, flow or block."""
    where = ".".join(keys)
    edits = []  # (start, end, replacement)
    missing = []
    for key, value in values.items():
        if key not in node:
            missing.append(key)
            continue
        line, col = node.lc.value(key)
        start = _offset(lines, line, col)
        if text[start] != "[":
            raise CellFileError(
                f"{path}:{line + 1}:{col + 1}: {where}.{key} is not written as [a, b, c]; "
                "write it so and teach again"
            )
        edits.append((start, _flow_end(text, start, "[", "]"), value))
    if missing:
        mapping_start = _offset(lines, node.lc.line, node.lc.col)
        if text[mapping_start] == "{":  # flow: add before its closing brace
            end = _flow_end(text, mapping_start, "{", "}") - 1
            edits.append((end, end, "".join(f", {k}: {values[k]}" for k in missing)))
        else:  # block: a line after the first key, at its indentation
            line, col = node.lc.key(next(iter(node)))
            if node.lc.value(next(iter(node)))[0] != line:
                raise CellFileError(
                    f"{path}:{line + 1}:{col + 1}: {where}: add {', '.join(missing)} by hand"
                )
            at = _offset(lines, line + 1, 0)
            edits.append((at, at, "".join(f"{' ' * col}{k}: {values[k]}\n" for k in missing)))
    for start, end, replacement in sorted(edits, reverse=True):
        text = text[:start] + replacement + text[end:]
    return text


def _insert(
    text: str,
    lines: list[str],
    root: Any,
    keys: tuple[str, ...],
    values: dict[str, str],
    path: Path,
) -> str:
    """Add a pose that is not in the file yet, as the first entry of its parent."""
    flow = "{" + ", ".join(f"{k}: {v}" for k, v in values.items()) + "}"
    parent = _mapping_at(root, keys[:-1], path)
    if parent is None or len(parent) == 0:
        if len(keys) == 2 and keys[0] not in root:
            sep = "" if text.endswith("\n") or not text else "\n"
            return f"{text}{sep}{keys[0]}:\n  {keys[1]}: {flow}\n"
        raise CellFileError(
            f"{path}: {'.'.join(keys[:-1])} is missing or empty; add it, then teach again"
        )
    first = next(iter(parent))
    line, col = parent.lc.key(first)
    if text[_offset(lines, parent.lc.line, parent.lc.col)] == "{":
        raise CellFileError(
            f"{path}:{line + 1}:{col + 1}: {'.'.join(keys[:-1])} is written inline "
            "({...}); write it as a block to teach into it"
        )
    at = _offset(lines, line, 0)
    return text[:at] + f"{' ' * col}{keys[-1]}: {flow}\n" + text[at:]


def _check(
    path: Path, before: str, after: str, keys: tuple[str, ...], values: dict[str, str]
) -> None:
    """The edit changed the pose at ``keys`` to ``values`` and nothing else."""
    from ruamel.yaml import YAML

    old, new = YAML(typ="safe", pure=True).load(before), YAML(typ="safe", pure=True).load(after)
    node = new
    for key in keys:
        node = node[key]
    for key, value in values.items():
        if not np.allclose(node[key], [float(v) for v in value.strip("[]").split(",")], atol=0):
            raise CellFileError(
                f"{path}: writing {'.'.join(keys)} failed; the file was left as it was"
            )
    target = old
    for key in keys[:-1]:
        target = target.setdefault(key, {}) if isinstance(target, dict) else target
    pose = target.get(keys[-1]) if isinstance(target.get(keys[-1]), dict) else {}
    target[keys[-1]] = {**pose, **{k: node[k] for k in values}}
    if old != new:
        raise CellFileError(
            f"{path}: writing {'.'.join(keys)} would change more than that pose; "
            "the file was left as it was"
        )
