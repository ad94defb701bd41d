"""Declaring the companion specifications' types and instances in asyncua's address space
(OPC 40010 Robotics, OPC 30050 PackML, OPC 10031-4 ISA-95 job control, OPC 40001-3
Machinery Jobs), and keeping their values current.

The standards' nodesets ship in no Python package we can depend on, and asyncua cannot
import the Machinery Jobs one (its issue 1869), so the types are declared in code from
the specifications' tables: each in the standard's namespace URI, with the standard's
BrowseName and numeric NodeId, structures with the standard's fields (so a client built
from the official nodeset encodes and decodes them alike). Instances live in the cell's
own namespace (string NodeIds) and carry the standards' BrowseNames.

Imports asyncua lazily, inside the functions.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

#: the standards' namespace URIs
DI_URI = "http://opcfoundation.org/UA/DI/"
ROBOTICS_URI = "http://opcfoundation.org/UA/Robotics/"
PACKML_URI = "http://opcfoundation.org/UA/PackML/"
ISA95_URI = "http://opcfoundation.org/UA/ISA95-JOBCONTROL_V2/"
MACHINERY_JOBS_URI = "http://opcfoundation.org/UA/Machinery/Jobs/"
MACHINERY_URI = "http://opcfoundation.org/UA/Machinery/"


@dataclass(frozen=True)
class Field:
    """One field of a structure: its name, its type (a VariantType name such as
    ``"String"``, or a NodeId of a declared DataType), array or not, optional or not."""

    name: str
    dtype: Any
    array: bool = False
    optional: bool = False


def node_id(identifier: int | str, namespace: int = 0) -> Any:
    from asyncua import ua

    return ua.NodeId(identifier, namespace)  # type: ignore[arg-type]  # plain int and str


def qname(name: str, namespace: int) -> Any:
    from asyncua import ua

    return ua.QualifiedName(name, namespace)


async def declare_struct(
    server: Any, ns: int, ident: int, encoding: int, name: str, fields: list[Field]
) -> Any:
    """A structure DataType ``ns;i=ident`` with its Default Binary encoding
    ``ns;i=encoding`` (the standard's ids); returns its NodeId."""
    from asyncua import ua
    from asyncua.common.manage_nodes import create_data_type, create_encoding
    from asyncua.common.structures104 import new_struct_field

    base = server.nodes.base_structure_type
    dtype = await create_data_type(base, node_id(ident, ns), qname(name, ns))
    enc = await create_encoding(dtype, node_id(encoding, ns), ua.QualifiedName("Default Binary", 0))
    definition = ua.StructureDefinition()
    definition.BaseDataType = base.nodeid
    definition.DefaultEncodingId = enc.nodeid
    definition.StructureType = (
        ua.StructureType.StructureWithOptionalFields
        if any(f.optional for f in fields)
        else ua.StructureType.Structure
    )
    definition.Fields = [
        new_struct_field(
            f.name,
            getattr(ua.VariantType, f.dtype) if isinstance(f.dtype, str) else f.dtype,
            array=f.array,
            optional=f.optional,
        )
        for f in fields
    ]
    await dtype.write_data_type_definition(definition)
    return dtype.nodeid


async def declare_enum(server: Any, ns: int, ident: int, name: str, names: list[str]) -> Any:
    """An Enumeration DataType ``ns;i=ident`` whose values are 0, 1, ... in ``names``'
    order; returns its NodeId."""
    from asyncua import ua
    from asyncua.common.manage_nodes import create_data_type

    dtype = await create_data_type(server.nodes.enum_data_type, node_id(ident, ns), qname(name, ns))
    definition = ua.EnumDefinition()
    for value, text in enumerate(names):
        item = ua.EnumField()
        item.Name, item.Value = text, value
        item.DisplayName = ua.LocalizedText(text)
        definition.Fields.append(item)
    await dtype.write_data_type_definition(definition)
    return dtype.nodeid


async def declare_object_type(
    server: Any, ns: int, ident: int, name: str, base: int | Any = None
) -> Any:
    """An ObjectType ``ns;i=ident`` below ``base`` (a NodeId, or an ns=0 id; default
    BaseObjectType); returns its NodeId."""
    from asyncua import ua

    parent = server.get_node(
        base if base is not None and not isinstance(base, int) else node_id(base or 58)
    )
    created = await parent.add_object_type(node_id(ident, ns), qname(name, ns))
    assert isinstance(created.nodeid, ua.NodeId)
    return created.nodeid


@dataclass
class Instances:
    """Adds an instance's nodes under string NodeIds ``prefix.path`` of the cell's
    namespace ``own`` and remembers the variables that change, for :class:`Values`."""

    own: int
    prefix: str
    variables: dict[str, tuple[Any, Any]] = field(default_factory=dict)  # key -> (node, vtype)

    async def obj(self, parent: Any, path: str, name: str, ns: int, typedef: Any = None) -> Any:
        return await parent.add_object(
            node_id(f"{self.prefix}.{path}", self.own),
            qname(name, ns),
            objecttype=typedef if typedef is not None else 58,
        )

    async def folder(self, parent: Any, path: str, name: str, ns: int) -> Any:
        return await parent.add_folder(node_id(f"{self.prefix}.{path}", self.own), qname(name, ns))

    async def var(
        self,
        parent: Any,
        path: str,
        name: str,
        ns: int,
        value: Any,
        vtype: str,
        *,
        datatype: Any = None,
        prop: bool = False,
        key: str | None = None,
    ) -> Any:
        """A variable (or a property, ``prop``) of VariantType ``vtype``; with ``key``
        it is kept current through :class:`Values` under that key."""
        from asyncua import ua

        variant_type = getattr(ua.VariantType, vtype)
        nid, browse = node_id(f"{self.prefix}.{path}", self.own), qname(name, ns)
        if prop:
            node = await parent.add_property(nid, browse, value, variant_type, datatype)
        else:
            node = await parent.add_variable(nid, browse, value, variant_type, datatype)
        if isinstance(value, list):
            await node.write_value_rank(1)
            await node.write_array_dimensions([0])
        if key is not None:
            self.variables[key] = (node, variant_type)
        return node


class Values:
    """Writes the variables :class:`Instances` keeps, when their value changed, straight
    into the address space (no service call: the server's own refresh)."""

    def __init__(self, server: Any, variables: dict[str, tuple[Any, Any]]) -> None:
        self._aspace = server.iserver.aspace
        self._variables = variables
        self._last: dict[str, Any] = {}

    async def write(self, values: dict[str, Any]) -> None:
        from asyncua import ua

        for key, value in values.items():
            if key in self._last and _same(self._last[key], value):
                continue
            self._last[key] = value
            node, variant_type = self._variables[key]
            await self._aspace.write_attribute_value(
                node.nodeid,
                ua.attribute_ids.AttributeIds.Value,
                ua.DataValue(ua.Variant(value, variant_type)),
            )


def _same(a: Any, b: Any) -> bool:
    try:
        return bool(a == b) and type(a) is type(b)
    except Exception:  # structures that do not compare: write them
        return False


async def add_method(
    parent: Any,
    own: int,
    path: str,
    name: str,
    ns: int,
    handler: Any,
    inputs: list[Any],
    outputs: list[Any],
) -> Any:
    """A method of the standard's BrowseName under a string NodeId of the cell's."""
    return await parent.add_method(node_id(path, own), qname(name, ns), handler, inputs, outputs)


def argument(name: str, datatype: Any, *, array: bool = False, description: str = "") -> Any:
    """A method argument; ``datatype`` a VariantType name or a DataType NodeId."""
    from asyncua import ua

    arg = ua.Argument()
    arg.Name = name
    arg.DataType = (
        node_id(getattr(ua.VariantType, datatype).value) if isinstance(datatype, str) else datatype
    )
    arg.ValueRank = 1 if array else -1
    if array:
        arg.ArrayDimensions = [0]
    arg.Description = ua.LocalizedText(description or name)
    return arg


def eu_information(unece_code: str, display: str, description: str) -> Any:
    """An EUInformation of the UNECE unit ``unece_code`` (OPC 10000-8's UnitId)."""
    from asyncua import ua

    unit_id = 0
    for ch in unece_code.upper():
        unit_id = (unit_id << 8) | ord(ch)
    return ua.EUInformation(
        NamespaceUri="http://www.opcfoundation.org/UA/units/un/cefact",
        UnitId=unit_id,
        DisplayName=ua.LocalizedText(display),
        Description=ua.LocalizedText(description),
    )
