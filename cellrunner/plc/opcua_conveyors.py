"""``Cell.Conveyors.<name>.Speed`` (SPEC section 13): each conveyor's measured belt speed,
mm/s (Int32), in the ``Cell`` object of the OPC UA server. A conveyor's node is added the
first time its speed is measured (the server does not read the cell file), under the
object ``Cell.Conveyors``, made then too."""

from __future__ import annotations

from typing import Any


class ConveyorNodes:
    """The conveyor nodes of one server: made as speeds appear, registered in the
    server's ``nodes`` and ``types`` (by key ``Conveyors.<name>.Speed``) so that its
    ordinary value writes publish them."""

    def __init__(self, cell: Any, idx: int, nodes: dict[str, Any], types: dict[str, Any]) -> None:
        self.cell, self.idx, self.nodes, self.types = cell, idx, nodes, types
        self._folder: Any = None

    async def values(self, speeds_mmps: tuple[tuple[str, int], ...]) -> dict[str, int]:
        """The values to write for ``speeds_mmps`` ((name, mm/s) pairs), nodes made first."""
        out = {}
        for name, speed in speeds_mmps:
            key = f"Conveyors.{name}.Speed"
            if key not in self.nodes:
                await self._add(name, key)
            out[key] = max(-(2**31), min(int(speed), 2**31 - 1))
        return out

    async def _add(self, name: str, key: str) -> None:
        from asyncua import ua

        idx = self.idx
        if self._folder is None:
            self._folder = await self.cell.add_object(
                _node_id("Cell.Conveyors", idx), ua.QualifiedName("Conveyors", idx)
            )
        conveyor = await self._folder.add_object(
            _node_id(f"Cell.Conveyors.{name}", idx), ua.QualifiedName(name, idx)
        )
        self.nodes[key] = await conveyor.add_variable(
            _node_id(f"Cell.{key}", idx), ua.QualifiedName("Speed", idx), 0, ua.VariantType.Int32
        )
        self.types[key] = ua.VariantType.Int32


def _node_id(identifier: str, namespace: int) -> Any:
    from asyncua import ua

    return ua.NodeId(identifier, namespace)  # type: ignore[arg-type]
