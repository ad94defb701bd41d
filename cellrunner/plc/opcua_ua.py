"""asyncua's values of plain Python values (its annotations ask for its own subclasses of
int and str, which plain values are as far as the wire is concerned)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from asyncua import ua


def node_id(identifier: int | str, namespace: int = 0) -> ua.NodeId:
    """asyncua's NodeId of a plain int or str."""
    from asyncua import ua

    return ua.NodeId(identifier, namespace)  # type: ignore[arg-type]


def status_code(code: int) -> ua.StatusCode:
    """asyncua's StatusCode of a plain int (its annotation asks for its UInt32 subclass)."""
    from asyncua import ua

    return ua.StatusCode(code)  # type: ignore[arg-type]


def argument(name: str, vtype: Any, description: str) -> Any:
    from asyncua import ua

    arg = ua.Argument()
    arg.Name = name
    arg.DataType = node_id(vtype.value)
    arg.ValueRank = -1
    arg.Description = ua.LocalizedText(description)
    return arg
