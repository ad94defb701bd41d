"""Reading YAML with positions: every key and value keeps its line and column.

ruamel.yaml composes the node tree; we build plain Python data from it ourselves so
that (1) every duplicate key is reported, not only the first, and (2) a path such as
``("robot", "limits", "tcp_speed")`` maps back to the place in the file where an error
must point.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cellrunner.errors import Diagnostic, InputError

if TYPE_CHECKING:
    from ruamel.yaml import YAML
    from ruamel.yaml.nodes import Node

PathKey = tuple[Any, ...]


@dataclass
class Source:
    """A loaded YAML document: plain ``data`` plus 1-based positions by path."""

    file: str
    data: Any
    value_pos: dict[PathKey, tuple[int, int]] = field(default_factory=dict)
    key_pos: dict[PathKey, tuple[int, int]] = field(default_factory=dict)
    #: SHA-256 (hex) of the file's text as read: what a plan of it is keyed by
    digest: str = ""

    def locate(self, path: PathKey, *, at_key: bool = False) -> tuple[int, int]:
        """Line and column of ``path``; falls back to its deepest known ancestor."""
        path = tuple(path)
        while path:
            table = self.key_pos if at_key else self.value_pos
            if path in table:
                return table[path]
            if path in self.value_pos:
                return self.value_pos[path]
            path, at_key = path[:-1], False
        return self.value_pos.get((), (1, 1))

    def diagnostic(
        self, path: PathKey, message: str, *, at_key: bool = False, severity: str = "error"
    ) -> Diagnostic:
        line, col = self.locate(path, at_key=at_key)
        return Diagnostic(self.file, line, col, message, severity)


def display_name(path: Path) -> str:
    """The file name as the user should see it: relative to the working dir if inside."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def load_yaml(path: Path) -> Source:
    """Parse ``path``; raises InputError (located) for unreadable files, YAML syntax
    errors and duplicate keys."""
    from ruamel.yaml import YAML
    from ruamel.yaml.error import MarkedYAMLError, YAMLError

    name = display_name(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"no such file: {name}", name) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read {name}: {exc}", name) from None
    yaml = YAML(typ="safe", pure=True)
    try:
        node = yaml.compose(text)
    except MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line, col = (mark.line + 1, mark.column + 1) if mark else (1, 1)
        problem = " ".join((exc.problem or exc.context or "invalid YAML").split())  # one line
        raise InputError([Diagnostic(name, line, col, f"YAML syntax: {problem}")]) from None
    except YAMLError as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else "invalid YAML"
        raise InputError(f"YAML syntax: {first}", name) from None
    import hashlib

    source = Source(name, None, digest=hashlib.sha256(text.encode()).hexdigest())
    if node is None:
        raise InputError([Diagnostic(name, 1, 1, "the file is empty")])
    errors: list[Diagnostic] = []
    source.data = _build(node, (), source, yaml, errors)
    if errors:
        raise InputError(errors)
    return source


def _build(node: Node, path: PathKey, source: Source, yaml: YAML, errors: list[Diagnostic]) -> Any:
    from ruamel.yaml.nodes import MappingNode, ScalarNode, SequenceNode

    mark = node.start_mark
    source.value_pos[path] = (mark.line + 1, mark.column + 1)
    if isinstance(node, MappingNode):
        out: dict[Any, Any] = {}
        for key_node, value_node in node.value:
            if not isinstance(key_node, ScalarNode):
                km = key_node.start_mark
                errors.append(
                    Diagnostic(
                        source.file,
                        km.line + 1,
                        km.column + 1,
                        "a key must be a plain value, not a list or mapping",
                    )
                )
                continue
            key = yaml.constructor.construct_object(key_node, deep=True)
            km = key_node.start_mark
            if key in out:
                first = source.key_pos[path + (key,)]
                errors.append(
                    Diagnostic(
                        source.file,
                        km.line + 1,
                        km.column + 1,
                        f"duplicate key {key!r} (first at line {first[0]})",
                    )
                )
                continue
            source.key_pos[path + (key,)] = (km.line + 1, km.column + 1)
            out[key] = _build(value_node, path + (key,), source, yaml, errors)
        return out
    if isinstance(node, SequenceNode):
        return [
            _build(item, path + (i,), source, yaml, errors) for i, item in enumerate(node.value)
        ]
    if node.tag and node.tag.startswith("!"):
        errors.append(
            Diagnostic(
                source.file, mark.line + 1, mark.column + 1, f"unsupported YAML tag {node.tag}"
            )
        )
        return None
    return yaml.constructor.construct_object(node, deep=True)
