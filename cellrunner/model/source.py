"""Reading YAML with positions: every key and value keeps its line and column.

ruamel.yaml composes the node tree; we build plain Python data from it ourselves so
that (1) every duplicate key is reported, not only the first, and (2) a path such as
``("robot", "limits", "tcp_speed")`` maps back to the place in the file where an error
must point.

A file is refused, located, before it can cost seconds or memory: more than
``MAX_FILE_BYTES``, nesting deeper than ``MAX_DEPTH``, more than ``MAX_NODES`` values
written or ``MAX_VALUES`` once aliases are expanded (an alias bomb), an alias inside
itself, or a number too long to be a quantity. Pure-Python YAML costs ~20 us a value, so
these bounds keep any file under a second.
"""

from __future__ import annotations

import errno
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cellrunner.errors import Diagnostic, InputError

if TYPE_CHECKING:
    from ruamel.yaml import YAML
    from ruamel.yaml.nodes import Node

PathKey = tuple[Any, ...]

MAX_FILE_BYTES = 512 << 10  # a cell file of a thousand taught frames is ~100 kB
MAX_DEPTH = 64  # the deepest real file (pick retry steps in a tool) nests ~10
MAX_NODES = 30_000  # values written in a file: a 1000-step task has ~5000
MAX_VALUES = 100_000  # values built, aliases expanded: the bound of an alias bomb
MAX_NUMBER_CHARS = 40  # digits of the longest int64 or float written out in full


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
    except (ValueError, OSError, RuntimeError):  # outside the cwd, or a symlink loop
        return str(path)


def file_problem(path: Path) -> str | None:
    """Why ``path`` cannot be read as a file (``"not found"``, ``"is a loop of symbolic
    links"``, ...), or None when it can."""
    try:
        if path.stat().st_mode & 0o170000 == 0o100000:
            return None
        return "is not a file"
    except FileNotFoundError:
        return "not found"
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            return "is a loop of symbolic links"
        return f"cannot be read ({exc.strerror or exc})"


def read_text(path: Path, name: str) -> str:
    """The file as text; InputError (at 1:1, or at the line and column of a byte that is
    not UTF-8) when it is missing, unreadable, a symlink loop, too big or not text."""
    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            raise InputError(
                f"{name} is {size / 1e6:.1f} MB; cell and task files are limited to "
                f"{MAX_FILE_BYTES / 1e6:.1f} MB",
                name,
            )
        raw = path.read_bytes()
    except FileNotFoundError:
        raise InputError(f"no such file: {name}", name) from None
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise InputError(f"cannot read {name}: a loop of symbolic links", name) from None
        raise InputError(f"cannot read {name}: {exc.strerror or exc}", name) from None
    try:
        return raw[:MAX_FILE_BYTES].decode("utf-8")
    except UnicodeDecodeError as exc:
        before = raw[: exc.start]
        line = before.count(b"\n") + 1
        col = len(before[before.rfind(b"\n") + 1 :].decode("utf-8", "replace")) + 1
        bad = raw[exc.start : exc.end].hex(" ")
        raise InputError(
            [Diagnostic(name, line, col, f"byte {bad} is not UTF-8 text; save the file as UTF-8")]
        ) from None


def load_yaml(path: Path) -> Source:
    """Parse ``path``; raises InputError (located) for unreadable files, YAML syntax
    errors, duplicate keys and the limits above."""
    from ruamel.yaml import YAML
    from ruamel.yaml.composer import MaxDepthExceededError
    from ruamel.yaml.error import MarkedYAMLError, YAMLError

    name = display_name(path)
    text = read_text(path, name)
    yaml = YAML(typ="safe", pure=True)
    yaml.max_depth = MAX_DEPTH
    yaml.Composer = _counting_composer()
    try:
        node = yaml.compose(text)
    except MaxDepthExceededError as exc:
        line, col = _mark(exc)
        raise InputError(
            [Diagnostic(name, line, col, f"nested more than {MAX_DEPTH} levels deep")]
        ) from None
    except _TooManyValues as exc:
        raise InputError(
            [Diagnostic(name, *exc.at, f"more than {MAX_NODES} values in one file")]
        ) from None
    except MarkedYAMLError as exc:
        line, col = _mark(exc)
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
    source.data = _Builder(source, yaml, errors).build(node, ())
    if errors:
        raise InputError(errors)
    return source


def _mark(exc: Any) -> tuple[int, int]:
    mark = exc.problem_mark or exc.context_mark
    return (mark.line + 1, mark.column + 1) if mark else (1, 1)


class _TooManyValues(Exception):
    """A file past MAX_NODES or MAX_VALUES; ``at`` is the 1-based line and column."""

    def __init__(self, at: tuple[int, int]) -> None:
        super().__init__(at)
        self.at = at


def _counting_composer() -> Any:
    """ruamel's composer, stopping at the MAX_NODES-th node it composes."""
    from ruamel.yaml.composer import Composer

    class CountingComposer(Composer):
        nodes = 0

        def compose_node(self, parent: Any, index: Any) -> Any:
            self.nodes += 1
            if self.nodes > MAX_NODES:
                mark = self.parser.peek_event().start_mark
                raise _TooManyValues((mark.line + 1, mark.column + 1))
            return super().compose_node(parent, index)

    return CountingComposer


@dataclass
class _Builder:
    """Plain data from the node tree, positions recorded, values counted."""

    source: Source
    yaml: YAML
    errors: list[Diagnostic]
    count: int = 0
    open_nodes: set[int] = field(default_factory=set)  # ids of the collections being built

    def build(self, node: Node, path: PathKey) -> Any:
        try:
            return self._build(node, path)
        except _TooManyValues as exc:
            message = f"more than {MAX_VALUES} values once its aliases are expanded"
            self.errors.append(Diagnostic(self.source.file, *exc.at, message))
            return None

    def _build(self, node: Node, path: PathKey) -> Any:
        from ruamel.yaml.nodes import MappingNode, SequenceNode

        mark = node.start_mark
        self.count += 1
        if self.count > MAX_VALUES:
            raise _TooManyValues((mark.line + 1, mark.column + 1))
        self.source.value_pos[path] = (mark.line + 1, mark.column + 1)
        if not isinstance(node, (MappingNode, SequenceNode)):
            return self._scalar(node)
        if id(node) in self.open_nodes:
            message = "an alias inside the value it names (it would never end)"
            self.errors.append(
                Diagnostic(self.source.file, mark.line + 1, mark.column + 1, message)
            )
            return None
        self.open_nodes.add(id(node))
        try:
            return (
                self._mapping(node, path)
                if isinstance(node, MappingNode)
                else [self._build(item, path + (i,)) for i, item in enumerate(node.value)]
            )
        finally:
            self.open_nodes.discard(id(node))

    def _mapping(self, node: Node, path: PathKey) -> dict[Any, Any]:
        from ruamel.yaml.nodes import ScalarNode

        out: dict[Any, Any] = {}
        for key_node, value_node in node.value:
            km = key_node.start_mark
            at = (km.line + 1, km.column + 1)
            if not isinstance(key_node, ScalarNode):
                message = "a key must be a plain value, not a list or mapping"
                self.errors.append(Diagnostic(self.source.file, *at, message))
                continue
            key = self._scalar(key_node)
            if key in out:
                first = self.source.key_pos[path + (key,)]
                message = f"duplicate key {key!r} (first at line {first[0]})"
                self.errors.append(Diagnostic(self.source.file, *at, message))
                continue
            self.source.key_pos[path + (key,)] = at
            out[key] = self._build(value_node, path + (key,))
        return out

    def _scalar(self, node: Node) -> Any:
        """One scalar; tags and numbers beyond any quantity are errors (value None)."""
        mark = node.start_mark
        tag = str(node.tag or "")
        problem = None
        if tag.startswith("!"):
            problem = f"unsupported YAML tag {tag}"
        elif tag.endswith((":int", ":float")) and len(str(node.value)) > MAX_NUMBER_CHARS:
            problem = (
                f"a number of {len(str(node.value))} characters; "
                f"numbers have at most {MAX_NUMBER_CHARS}"
            )
        if problem is None:
            value = self.yaml.constructor.construct_object(node, deep=True)
            if not isinstance(value, float) or math.isfinite(value):
                return value
            problem = f"{node.value} is not a finite number"
        self.errors.append(Diagnostic(self.source.file, mark.line + 1, mark.column + 1, problem))
        return None
