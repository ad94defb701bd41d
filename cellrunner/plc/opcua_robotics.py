"""OPC 40010 Robotics: the arm, its controller and its safety as a generic client expects
them (SPEC 13).

::

    <machine>/MotionDeviceSystem               (MotionDeviceSystemType)
      MotionDevices/Arm                        (MotionDeviceType)
        Manufacturer, Model, ProductCode, SerialNumber, MotionDeviceCategory (1 articulated)
        ParameterSet/ SpeedOverride Double (1), InControl Boolean (a job runs)
        Axes/ Base, Shoulder, Elbow, Wrist1, Wrist2, Wrist3   (AxisType)
          MotionProfile (1 rotary)
          ParameterSet/ ActualPosition Double (deg), ActualSpeed Double (deg/s)
        PowerTrains/
      Controllers/Controller                   (ControllerType)
        Manufacturer, Model, ProductCode, SerialNumber
        Software/  CurrentUser/Level
        TaskControls/Task                      (TaskControlType)
          ComponentName, ParameterSet/ TaskProgramName String (the running task, "" when
          none), TaskProgramLoaded Boolean
      SafetyStates/Safety                      (SafetyStateType)
        ParameterSet/ OperationalMode (4 automatic external), EmergencyStop, ProtectiveStop

The values come from :class:`~cellrunner.model.cellport.ArmStatus`, the last measurement
the control loop made (read without a lock, never from the robot), refreshed with the
server's other variables every :data:`~cellrunner.plc.opcua.REFRESH_PERIOD_S`. BrowseNames
are in the Robotics and DI (OPC 10000-100) namespaces, as the standard places them.
"""

from __future__ import annotations

import math
from typing import Any

from cellrunner.model.cellport import ArmStatus, CellStatus
from cellrunner.plc.opcua_nodes import (
    DI_URI,
    ROBOTICS_URI,
    Instances,
    Values,
    declare_enum,
    declare_object_type,
    eu_information,
    node_id,
)

#: the arm's joints, base to wrist 3, as UR names them
AXES = ("Base", "Shoulder", "Elbow", "Wrist1", "Wrist2", "Wrist3")
_COMPONENT_TYPE = 15063  # DI
_TYPES = {
    "MotionDeviceSystemType": 1002,
    "ControllerType": 1003,
    "MotionDeviceType": 1004,
    "TaskControlType": 1011,
    "SafetyStateType": 1013,
    "UserType": 18175,
    "AxisType": 16601,
}
_ENUMS = {  # name: (id, values in order)
    "OperationalModeEnumeration": (
        3006,
        ["OTHER", "MANUAL_REDUCED_SPEED", "MANUAL_HIGH_SPEED", "AUTOMATIC", "AUTOMATIC_EXTERNAL"],
    ),
    "AxisMotionProfileEnumeration": (
        3008,
        ["OTHER", "ROTARY", "ROTARY_ENDLESS", "LINEAR", "LINEAR_ENDLESS"],
    ),
    "ExecutionModeEnumeration": (18191, ["CYCLE", "CONTINUOUS", "STEP"]),
    "MotionDeviceCategoryEnumeration": (
        18193,
        [
            "OTHER",
            "ARTICULATED_ROBOT",
            "SCARA_ROBOT",
            "CARTESIAN_ROBOT",
            "SPHERICAL_ROBOT",
            "PARALLEL_ROBOT",
            "CYLINDRICAL_ROBOT",
        ],
    ),
}
ARTICULATED_ROBOT, ROTARY, AUTOMATIC_EXTERNAL = 1, 1, 4


async def declare_types(server: Any) -> tuple[int, int]:
    """Register the DI and Robotics namespaces and declare the types the arm's objects
    use; (DI namespace index, Robotics namespace index)."""
    di = await server.register_namespace(DI_URI)
    rob = await server.register_namespace(ROBOTICS_URI)
    component = await declare_object_type(server, di, _COMPONENT_TYPE, "ComponentType")
    for name, ident in _TYPES.items():
        base = None if name == "UserType" else component
        await declare_object_type(server, rob, ident, name, base)
    for name, (ident, values) in _ENUMS.items():
        await declare_enum(server, rob, ident, name, values)
    return di, rob


class RoboticsObjects:
    """The MotionDeviceSystem of one OPC UA server, kept current from :class:`ArmStatus`."""

    def __init__(self) -> None:
        self._values: Values | None = None
        self._identity: tuple[str, str, str] | None = None

    async def build(self, server: Any, machine: Any, own: int, di: int, rob: int) -> Any:
        """The objects under ``machine``; returns the MotionDeviceSystem's node."""
        nodes = Instances(own, "Robotics")
        system = await nodes.obj(
            machine, "Self", "MotionDeviceSystem", own, _type(rob, "MotionDeviceSystemType")
        )
        await self._build_arm(nodes, system, own, di, rob)
        await self._build_controller(nodes, system, own, di, rob)
        await _build_safety(nodes, system, own, di, rob)
        self._values = Values(server, nodes.variables)
        return system

    async def _build_arm(self, nodes: Instances, system: Any, own: int, di: int, rob: int) -> None:
        """MotionDevices/Arm: its identity, category, speed override and axes."""
        devices = await nodes.folder(system, "MotionDevices", "MotionDevices", rob)
        arm = await nodes.obj(devices, "Arm", "Arm", own, _type(rob, "MotionDeviceType"))
        await self._identify(nodes, arm, "Arm", di, rob)
        await nodes.var(
            arm, "Arm.MotionDeviceCategory", "MotionDeviceCategory", rob, ARTICULATED_ROBOT,
            "Int32", datatype=_enum(rob, "MotionDeviceCategoryEnumeration"), prop=True,
        )  # fmt: skip
        params = await nodes.obj(arm, "Arm.ParameterSet", "ParameterSet", di)
        await nodes.var(params, "Arm.SpeedOverride", "SpeedOverride", rob, 1.0, "Double")
        await nodes.var(
            params, "Arm.InControl", "InControl", rob, False, "Boolean", key="InControl"
        )
        axes = await nodes.folder(arm, "Arm.Axes", "Axes", rob)
        degrees = eu_information("DD", "°", "degree")
        degrees_per_s = eu_information("E96", "°/s", "degree per second")
        for axis in AXES:
            path = f"Arm.Axes.{axis}"
            node = await nodes.obj(axes, path, axis, own, _type(rob, "AxisType"))
            await nodes.var(
                node, f"{path}.MotionProfile", "MotionProfile", rob, ROTARY, "Int32",
                datatype=_enum(rob, "AxisMotionProfileEnumeration"), prop=True,
            )  # fmt: skip
            axis_params = await nodes.obj(node, f"{path}.ParameterSet", "ParameterSet", di)
            for name, unit in (("ActualPosition", degrees), ("ActualSpeed", degrees_per_s)):
                var = await nodes.var(
                    axis_params, f"{path}.{name}", name, rob, 0.0, "Double",
                    key=f"{axis}.{name}",
                )  # fmt: skip
                await nodes.var(
                    var, f"{path}.{name}.EngineeringUnits", "EngineeringUnits", 0, unit,
                    "ExtensionObject", datatype=node_id(887), prop=True,
                )  # fmt: skip
        await nodes.folder(arm, "Arm.PowerTrains", "PowerTrains", rob)

    async def _build_controller(
        self, nodes: Instances, system: Any, own: int, di: int, rob: int
    ) -> None:
        """Controllers/Controller: its identity, user and the task it runs."""
        from asyncua import ua

        controllers = await nodes.folder(system, "Controllers", "Controllers", rob)
        controller = await nodes.obj(
            controllers, "Controller", "Controller", own, _type(rob, "ControllerType")
        )
        await self._identify(nodes, controller, "Controller", di, rob)
        await nodes.folder(controller, "Controller.Software", "Software", rob)
        user = await nodes.obj(
            controller, "Controller.CurrentUser", "CurrentUser", rob, _type(rob, "UserType")
        )
        await nodes.var(user, "Controller.CurrentUser.Level", "Level", rob, "operator", "String")
        tasks = await nodes.folder(controller, "Controller.TaskControls", "TaskControls", rob)
        task = await nodes.obj(tasks, "Task", "Task", own, _type(rob, "TaskControlType"))
        await nodes.var(
            task, "Task.ComponentName", "ComponentName", di, ua.LocalizedText("cellrunner task"),
            "LocalizedText", prop=True,
        )  # fmt: skip
        task_params = await nodes.obj(task, "Task.ParameterSet", "ParameterSet", di)
        await nodes.var(
            task_params, "Task.TaskProgramName", "TaskProgramName", rob, "", "String",
            key="TaskProgramName",
        )  # fmt: skip
        await nodes.var(
            task_params, "Task.TaskProgramLoaded", "TaskProgramLoaded", rob, False, "Boolean",
            key="TaskProgramLoaded",
        )  # fmt: skip

    @staticmethod
    async def _identify(nodes: Instances, parent: Any, path: str, di: int, rob: int) -> None:
        from asyncua import ua

        for name, vtype, value in (
            ("Manufacturer", "LocalizedText", ua.LocalizedText("")),
            ("Model", "LocalizedText", ua.LocalizedText("")),
            ("ProductCode", "String", ""),
            ("SerialNumber", "String", ""),
        ):
            await nodes.var(
                parent, f"{path}.{name}", name, di, value, vtype, prop=True, key=f"{path}.{name}"
            )

    async def publish(self, status: CellStatus, arm: ArmStatus | None) -> None:
        from asyncua import ua

        if self._values is None or arm is None:
            return
        values: dict[str, Any] = {
            "InControl": status.busy,
            "TaskProgramName": arm.task,
            "TaskProgramLoaded": bool(arm.task),
            "EmergencyStop": arm.emergency_stop,
            "ProtectiveStop": arm.protective_stop,
        }
        for axis, q, qd in zip(AXES, arm.q_rad, arm.qd_rad_s, strict=False):
            values[f"{axis}.ActualPosition"] = math.degrees(q)
            values[f"{axis}.ActualSpeed"] = math.degrees(qd)
        identity = (arm.model, arm.serial_number, arm.controller)
        if identity != self._identity:
            self._identity = identity
            model = arm.model.upper().replace("E", "e") if arm.model else ""
            for part, label in (("Arm", model), ("Controller", arm.controller or model)):
                values[f"{part}.Manufacturer"] = ua.LocalizedText(arm.manufacturer)
                values[f"{part}.Model"] = ua.LocalizedText(label)
                values[f"{part}.ProductCode"] = arm.model
                values[f"{part}.SerialNumber"] = arm.serial_number
        await self._values.write(values)


async def _build_safety(nodes: Instances, system: Any, own: int, di: int, rob: int) -> None:
    """SafetyStates/Safety: the operational mode and the stops."""
    states = await nodes.folder(system, "SafetyStates", "SafetyStates", rob)
    safety = await nodes.obj(states, "Safety", "Safety", own, _type(rob, "SafetyStateType"))
    safety_params = await nodes.obj(safety, "Safety.ParameterSet", "ParameterSet", di)
    await nodes.var(
        safety_params, "Safety.OperationalMode", "OperationalMode", rob, AUTOMATIC_EXTERNAL,
        "Int32", datatype=_enum(rob, "OperationalModeEnumeration"),
    )  # fmt: skip
    for name in ("EmergencyStop", "ProtectiveStop"):
        await nodes.var(safety_params, f"Safety.{name}", name, rob, False, "Boolean", key=name)


def _type(rob: int, name: str) -> Any:
    """The Robotics namespace's ObjectType ``name``."""
    return node_id(_TYPES[name], rob)


def _enum(rob: int, name: str) -> Any:
    """The Robotics namespace's enumeration DataType ``name``."""
    return node_id(_ENUMS[name][0], rob)
