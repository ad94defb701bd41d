"""A check that an object implements a Protocol: every method the Protocol declares
exists with the same parameters (names, kinds, and the Protocol's defaults; an
implementation may add defaults) and is callable -- what
``isinstance`` on a ``runtime_checkable`` Protocol does not check (it only looks for the
names)."""

from __future__ import annotations

import inspect
from typing import Any


def assert_implements(obj: Any, protocol: type) -> None:
    members = [
        name
        for name, value in vars(protocol).items()
        if inspect.isfunction(value) and not name.startswith("_")
    ]
    assert members, f"{protocol.__name__} declares no methods"
    for name in members:
        impl = getattr(obj, name, None)
        assert callable(impl), f"{type(obj).__name__} lacks {protocol.__name__}.{name}"
        wanted = list(inspect.signature(getattr(protocol, name)).parameters.values())[
            1:
        ]  # without self
        got = list(inspect.signature(impl).parameters.values())
        empty = inspect.Parameter.empty
        same = [(p.name, p.kind) for p in got] == [(p.name, p.kind) for p in wanted] and all(
            g.default == w.default
            for g, w in zip(got, wanted, strict=True)
            if w.default is not empty
        )
        assert same, (
            f"{type(obj).__name__}.{name}{inspect.signature(impl)} differs from "
            f"{protocol.__name__}.{name}{inspect.signature(getattr(protocol, name))}"
        )
    for name in getattr(protocol, "__annotations__", {}):
        assert hasattr(obj, name), f"{type(obj).__name__} lacks {protocol.__name__}.{name}"
