"""The cell in the plant's language (SPEC 13): OPC 40010 Robotics, OPC 30050 PackML and
ISA-95 job orders beside ``Objects/Cell``, under one machine object::

    Objects/<cell name>            (the cell's namespace; "CellMachine" if the cell is
      JobManagement                 named "Cell")      see cellrunner.plc.opcua_jobs
      PackML                                           see cellrunner.plc.opcua_packml
      MotionDeviceSystem                               see cellrunner.plc.opcua_robotics

and where the standards say clients look: ``Objects/Machines`` (OPC 40001-1) organizes
the cell's object, ``Objects/DeviceSet`` (OPC 10000-100) its MotionDeviceSystem.

The server builds them once (:meth:`Companions.build`), refreshes them with ``Cell``
(:meth:`Companions.publish`) and hands them each finished job (:meth:`Companions.finish`).
"""

from __future__ import annotations

from typing import Any

from cellrunner.model.cellport import ArmPort, CellPort, CellStatus, JobResult, JobSource
from cellrunner.plc import opcua_jobs, opcua_packml, opcua_robotics
from cellrunner.plc.opcua_nodes import DI_URI, MACHINERY_URI, declare_members, node_id, qname

#: the standards' entry points: (namespace URI, id, BrowseName)
MACHINES = (MACHINERY_URI, 1001, "Machines")
DEVICE_SET = (DI_URI, 5001, "DeviceSet")


async def _declare_types_members(machine: Any, own: int, max_nodes: int = 400) -> None:
    """Each standard ObjectType used below ``machine`` gets the members its first
    instance shows (:func:`~cellrunner.plc.opcua_nodes.declare_members`), containers
    before their parts."""
    from asyncua import ua

    done: set[Any] = set()
    queue, seen = [machine], 0
    while queue and seen < max_nodes:
        node = queue.pop(0)
        for child in await node.get_children(nodeclassmask=ua.NodeClass.Object):
            seen += 1
            typedef = await child.read_type_definition()
            if (
                typedef is not None
                and typedef.NamespaceIndex not in (0, own)
                and typedef not in done
            ):
                done.add(typedef)
                await declare_members(typedef, child)
            queue.append(child)


class Companions:
    """The three companion specifications' objects of one OPC UA server."""

    def __init__(self, port: CellPort, source: JobSource) -> None:
        self.port = port
        self.jobs = opcua_jobs.JobOrderServer(port, source)
        self.packml = opcua_packml.PackMLObject()
        self.robotics = opcua_robotics.RoboticsObjects()

    @property
    def reading_methods(self) -> list[Any]:
        """The methods that only read (a viewer may call them)."""
        return list(self.jobs.reading_methods)

    async def build(self, server: Any, own: int, cell_name: str) -> None:
        """Declare the standards' types, then the machine object and its three parts."""
        from asyncua import ua

        isa, jobs = await opcua_jobs.declare_types(server)
        packml = await opcua_packml.declare_types(server)
        di, rob = await opcua_robotics.declare_types(server)
        await server.load_data_type_definitions()  # the structures' Python classes
        name = cell_name if cell_name and cell_name != "Cell" else "CellMachine"
        machine = await server.nodes.objects.add_object(node_id("Machine", own), qname(name, own))
        await machine.write_attribute(
            ua.attribute_ids.AttributeIds.DisplayName,
            ua.DataValue(ua.Variant(ua.LocalizedText(cell_name))),
        )
        await self.jobs.build(server, machine, own, isa, jobs)
        await self.packml.build(server, machine, own, packml, cell_name)
        system = await self.robotics.build(server, machine, own, di, rob)
        await _declare_types_members(machine, own)
        for (uri, ident, browse), target in ((MACHINES, machine), (DEVICE_SET, system)):
            ns = await server.register_namespace(uri)
            folder = await server.nodes.objects.add_folder(node_id(ident, ns), qname(browse, ns))
            await folder.add_reference(target.nodeid, ua.object_ids.ObjectIds.Organizes)

    async def publish(self, status: CellStatus) -> None:
        arm = self.port.arm() if isinstance(self.port, ArmPort) else None
        await self.packml.publish(status)
        await self.robotics.publish(status, arm)
        await self.jobs.follow(status)

    async def finish(self, result: JobResult) -> None:
        self.packml.finish(result)
        await self.jobs.finish(result)
