"""The ISA-95 job control (OPC 10031-4 V2) and Machinery Jobs (OPC 40001-3) types, declared
from the specifications' tables in the standards' namespaces with their NodeIds,
BrowseNames and structure fields: asyncua cannot import the Machinery Jobs nodeset (its
issue 1869). :mod:`cellrunner.plc.opcua_jobs` builds the objects of these types.
"""

from __future__ import annotations

from typing import Any

from cellrunner.plc.opcua_nodes import (
    ISA95_URI,
    MACHINERY_JOBS_URI,
    Field,
    declare_object_type,
    declare_struct,
    node_id,
    qname,
)

# the standard's numeric ids (ISA95-JOBCONTROL_V2 and Machinery/Jobs)
DATATYPES = {  # name: (DataType id, Default Binary encoding id)
    "ISA95PropertyDataType": (3002, 5002),
    "ISA95ParameterDataType": (3003, 5005),
    "ISA95EquipmentDataType": (3005, 5008),
    "ISA95StateDataType": (3006, 5029),
    "ISA95WorkMasterDataType": (3007, 5011),
    "ISA95JobOrderDataType": (3008, 5014),
    "ISA95MaterialDataType": (3010, 5017),
    "ISA95PersonnelDataType": (3011, 5020),
    "ISA95PhysicalAssetDataType": (3012, 5023),
    "ISA95JobResponseDataType": (3013, 5026),
    "ISA95JobOrderAndStateDataType": (3015, 5032),
}
RECEIVER_TYPE, PROVIDER_TYPE, STATUS_EVENT_TYPE = 1002, 1003, 1006
JOB_MANAGEMENT_TYPE = 1003  # in Machinery/Jobs
_FINITE_STATE_MACHINE_TYPE, _BASE_EVENT_TYPE = 2771, 2041
_ENUMERATION_TYPES = {"RelativePath": 540, "EUInformation": 887, "DecimalString": 12878}


def _fields(ns: int) -> dict[str, list[Field]]:
    """The structures' fields, in the specification's order (OPC 10031-4 V2, 6.3)."""
    return {**_resource_fields(ns), **_job_fields(ns)}


def _datatype(ns: int, name: str) -> Any:
    """The DataType node of ``name``: ISA-95's (namespace ``ns``) or a base one."""
    if name in _ENUMERATION_TYPES:
        return node_id(_ENUMERATION_TYPES[name])
    return node_id(DATATYPES[name][0], ns)


def _resource_fields(ns: int) -> dict[str, list[Field]]:
    """Properties, parameters, the resources and a state."""

    def t(name: str) -> Any:
        return _datatype(ns, name)

    prop = t("ISA95PropertyDataType")
    param = t("ISA95ParameterDataType")
    eu = t("EUInformation")
    quantity = t("DecimalString")
    text = "LocalizedText"

    def resource(use: str) -> list[Field]:
        return [
            Field("ID", "String"),
            Field("Description", text, array=True, optional=True),
            Field(use, "String", optional=True),
            Field("Quantity", quantity, optional=True),
            Field("EngineeringUnits", eu, optional=True),
            Field("Properties", prop, array=True, optional=True),
        ]

    return {
        "ISA95PropertyDataType": [
            Field("ID", "String"),
            Field("Value", "Variant"),
            Field("Description", text, array=True, optional=True),
            Field("EngineeringUnits", eu, optional=True),
            Field("Subproperties", prop, array=True, optional=True),
        ],
        "ISA95ParameterDataType": [
            Field("ID", "String"),
            Field("Value", "Variant"),
            Field("Description", text, array=True, optional=True),
            Field("EngineeringUnits", eu, optional=True),
            Field("Subparameters", param, array=True, optional=True),
        ],
        "ISA95EquipmentDataType": resource("EquipmentUse"),
        "ISA95PersonnelDataType": resource("PersonnelUse"),
        "ISA95PhysicalAssetDataType": resource("PhysicalAssetUse"),
        "ISA95MaterialDataType": [
            Field("MaterialClassID", "String", optional=True),
            Field("MaterialDefinitionID", "String", optional=True),
            Field("MaterialLotID", "String", optional=True),
            Field("MaterialSublotID", "String", optional=True),
            Field("Description", text, array=True, optional=True),
            Field("MaterialUse", "String", optional=True),
            Field("Quantity", quantity, optional=True),
            Field("EngineeringUnits", eu, optional=True),
            Field("Properties", prop, array=True, optional=True),
        ],
        "ISA95StateDataType": [
            Field("BrowsePath", t("RelativePath")),
            Field("StateText", text),
            Field("StateNumber", "UInt32"),
        ],
    }


def _job_fields(ns: int) -> dict[str, list[Field]]:
    """Work masters, job orders and their responses."""

    def t(name: str) -> Any:
        return _datatype(ns, name)

    param = t("ISA95ParameterDataType")
    text = "LocalizedText"
    return {
        "ISA95WorkMasterDataType": [
            Field("ID", "String"),
            Field("Description", text, optional=True),
            Field("Parameters", param, array=True, optional=True),
        ],
        "ISA95JobOrderDataType": [
            Field("JobOrderID", "String"),
            Field("Description", text, array=True, optional=True),
            Field("WorkMasterID", t("ISA95WorkMasterDataType"), array=True, optional=True),
            Field("StartTime", "DateTime", optional=True),
            Field("EndTime", "DateTime", optional=True),
            Field("Priority", "Int16", optional=True),
            Field("JobOrderParameters", param, array=True, optional=True),
            Field("PersonnelRequirements", t("ISA95PersonnelDataType"), True, True),
            Field("EquipmentRequirements", t("ISA95EquipmentDataType"), True, True),
            Field("PhysicalAssetRequirements", t("ISA95PhysicalAssetDataType"), True, True),
            Field("MaterialRequirements", t("ISA95MaterialDataType"), True, True),
        ],
        "ISA95JobResponseDataType": [
            Field("JobResponseID", "String"),
            Field("Description", text, optional=True),
            Field("JobOrderID", "String"),
            Field("StartTime", "DateTime", optional=True),
            Field("EndTime", "DateTime", optional=True),
            Field("JobState", t("ISA95StateDataType"), array=True),
            Field("JobResponseData", param, array=True, optional=True),
            Field("PersonnelActuals", t("ISA95PersonnelDataType"), True, True),
            Field("EquipmentActuals", t("ISA95EquipmentDataType"), True, True),
            Field("PhysicalAssetActuals", t("ISA95PhysicalAssetDataType"), True, True),
            Field("MaterialActuals", t("ISA95MaterialDataType"), True, True),
        ],
        "ISA95JobOrderAndStateDataType": [
            Field("JobOrder", t("ISA95JobOrderDataType")),
            Field("State", t("ISA95StateDataType"), array=True),
        ],
    }


async def declare_types(server: Any) -> tuple[int, int]:
    """Register the ISA-95 job control and Machinery Jobs namespaces and declare their
    types; (ISA-95 namespace index, Machinery Jobs namespace index)."""
    from asyncua import ua

    isa = await server.register_namespace(ISA95_URI)
    jobs = await server.register_namespace(MACHINERY_JOBS_URI)
    for name, fields in _fields(isa).items():
        ident, encoding = DATATYPES[name]
        await declare_struct(server, isa, ident, encoding, name, fields)
    fsm = node_id(_FINITE_STATE_MACHINE_TYPE)
    await declare_object_type(server, isa, RECEIVER_TYPE, "ISA95JobOrderReceiverObjectType", fsm)
    await declare_object_type(server, isa, PROVIDER_TYPE, "ISA95JobResponseProviderObjectType")
    await declare_object_type(server, jobs, JOB_MANAGEMENT_TYPE, "JobManagementType")
    event = await server.get_node(node_id(_BASE_EVENT_TYPE)).add_object_type(
        node_id(STATUS_EVENT_TYPE, isa), qname("ISA95JobOrderStatusEventType", isa)
    )
    for name, dtype, array in (
        ("JobOrder", "ISA95JobOrderDataType", False),
        ("JobResponse", "ISA95JobResponseDataType", False),
        ("JobState", "ISA95StateDataType", True),
    ):
        prop = await event.add_property(
            isa, name, None, ua.VariantType.ExtensionObject, node_id(DATATYPES[dtype][0], isa)
        )
        await prop.write_value_rank(1 if array else -1)
        await prop.set_modelling_rule(True)
    return isa, jobs
