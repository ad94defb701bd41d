"""Declaring the companion specifications' types and instances in asyncua's address space
(OPC 40010 Robotics, OPC 30050 PackML, OPC 10031-4 ISA-95 job control, OPC 40001-3
Machinery Jobs), and keeping their values current.

The standards' nodesets ship in no Python package we can depend on, and asyncua cannot
import the Machinery Jobs one (its issue 1869), so the types are declared in code from
the specifications' tables: each in the standard's namespace URI, with the standard's
BrowseName and numeric NodeId, structures with the standard's fields (so a client built
from the official nodeset encodes and decodes them alike). Instances live in the cell's
own namespace (string NodeIds) and carry the standards' BrowseNames; once built, each
ObjectType is given the members its instance shows as Mandatory InstanceDeclarations
(:func:`declare_members`).

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


async def declare_members(type_id: Any, instance: Any, depth: int = 3) -> None:
    """Give the ObjectType ``type_id`` the InstanceDeclarations its ``instance`` shows
    (Mandatory, in the type's namespace), so a client reading the type sees the members
    the standard's table lists; down to ``depth`` levels. The contents of folders (the
    standard's placeholders: axes, controllers...) and children named in the cell's own
    namespace are left out. Call after the instances are built: an instance made later of
    the type gets these members from asyncua."""
    type_node = _node(instance, type_id)
    prefix = (await type_node.read_browse_name()).Name
    await _mirror(type_node, instance, type_id.NamespaceIndex, prefix, depth)


def _node(like: Any, node_id_: Any) -> Any:
    from asyncua.common.node import Node

    return Node(like.session, node_id_)


async def _mirror(target: Any, source: Any, ns: int, prefix: str, depth: int) -> None:
    from asyncua import ua

    own = source.nodeid.NamespaceIndex
    properties = {n.nodeid for n in await source.get_properties()}
    present = {_key(await c.read_browse_name()) for c in await target.get_children()}
    for child in await source.get_children():
        name = await child.read_browse_name()
        if name.NamespaceIndex == own or _key(name) in present:
            if _key(name) in present and depth > 1:
                await _mirror(
                    await target.get_child(name), child, ns, f"{prefix}.{name.Name}", depth - 1
                )
            continue
        path = node_id(f"{prefix}.{name.Name}", ns)
        node_class = await child.read_node_class()
        if node_class == ua.NodeClass.Variable:
            value = await child.read_data_value()
            dtype = await child.read_data_type()
            add = target.add_property if child.nodeid in properties else target.add_variable
            made = await add(path, name, value.Value.Value, value.Value.VariantType, dtype)
            await made.write_value_rank(await child.read_value_rank())
        elif node_class == ua.NodeClass.Object:
            typedef = await child.read_type_definition()
            made = await target.add_object(path, name, objecttype=typedef)
            if depth > 1 and typedef != node_id(61):  # a folder's contents are placeholders
                await _mirror(made, child, ns, f"{prefix}.{name.Name}", depth - 1)
        elif node_class == ua.NodeClass.Method:
            made = await target.add_method(
                path, name, _declaration, await _arguments(child, "InputArguments"),
                await _arguments(child, "OutputArguments"),
            )  # fmt: skip
        else:
            continue
        await made.set_modelling_rule(True)


def _key(name: Any) -> tuple[int, str]:
    return (int(name.NamespaceIndex), str(name.Name))


async def _arguments(method: Any, which: str) -> list[Any]:
    try:
        found = await method.get_child(f"0:{which}")
    except Exception:  # no arguments
        return []
    value = await found.read_value()
    return list(value or [])


def _declaration(parent: Any, *args: Any) -> Any:
    """A type's method declaration is not called (a client calls an instance's method)."""
    from asyncua import ua

    return ua.StatusCode(ua.status_codes.StatusCodes.BadNotImplemented)  # type: ignore[arg-type]
