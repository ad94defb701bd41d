"""The twin's description of a loaded cell file (the twin itself never reads YAML)."""

from __future__ import annotations

import numpy as np

from cellrunner.model.expand import frame_pose
from cellrunner.model.gripper import gripper_channels
from cellrunner.model.load import LoadedCell


def description_of(loaded: LoadedCell):
    """A :class:`TwinDescription` of ``loaded``: arm, mount, tool, gripper, fixtures, parts, IO."""
    from cellrunner.backends.sim.description import GripperDescription, PartDescription, TwinDescription

    c = loaded.cell
    outputs, inputs = c.io.outputs, c.io.inputs
    gripper = None
    g = c.tool.gripper
    io_outputs, io_inputs = list(dict.fromkeys(outputs.values())), list(dict.fromkeys(inputs.values()))
    close, _, sensor = gripper_channels(g, outputs, inputs)
    if close is not None:
        gripper = GripperDescription(
            stroke_m=g.stroke, jaw_speed_mps=g.stroke / 2 / g.close_time,
            close_output=close[0], close_value=close[1], closed_sensor_input=sensor,
            open_sensor_input=inputs.get(g.open_sensor) if g.open_sensor else None)
        io_outputs += [close[0]] if close[0] not in io_outputs else []
        io_inputs += [sensor] if sensor and sensor not in io_inputs else []
    parts = [_part(loaded, p) for p in c.parts]
    return TwinDescription(
        spec=loaded.spec, T_world_base=c.robot.mount.matrix(), T_flange_tcp=c.tool.tcp.matrix(),
        q_home_rad=tuple(np.radians(c.robot.home)), tool_geometry=tuple(loaded.tool_shapes()),
        payload_mass_kg=max(c.tool.payload.mass, 0.1), payload_cog_m=tuple(c.tool.payload.cog),
        gripper=gripper, fixtures=tuple(loaded.fixture_shapes()), parts=tuple(parts),
        io_outputs=tuple(io_outputs), io_inputs=tuple(io_inputs),
        input_rules=_input_rules(c), name=c.cell)


def _part(loaded: LoadedCell, part):
    """A part upright at its frame, moved by its twin-only ``offset``."""
    from cellrunner.backends.sim.description import PartDescription

    T_world_grip = frame_pose(loaded.cell, part.at)
    if part.offset is not None:
        T_world_grip = T_world_grip @ part.offset.matrix()
    return PartDescription(part.name, part.to_shape(loaded.resolve), part.mass, _upright(T_world_grip), part.friction)


def _input_rules(cell) -> tuple:
    """The ``sim: inputs`` rules in channels and world metres."""
    from cellrunner.backends.sim.input_rules import InputRuleDescription

    if cell.sim is None:
        return ()
    out = []
    for name, rule in cell.sim.inputs.items():
        channel = cell.io.inputs[name]
        if rule.part_at is not None:
            point = tuple(float(v) for v in frame_pose(cell, rule.part_at)[:3, 3])
            out.append(InputRuleDescription(channel, "part_at", point_world_m=point, within_m=rule.within,
                                            invert=rule.invert))
        else:
            kind = "follows" if rule.follows is not None else "pulse_after"
            output = cell.io.outputs[rule.follows or rule.pulse_after]
            out.append(InputRuleDescription(channel, kind, output=output, delay_s=rule.delay, width_s=rule.width,
                                            invert=rule.invert))
    return tuple(out)


def _upright(T_world_frame: np.ndarray) -> np.ndarray:
    """A part lies upright at its frame: the frame's position and yaw, no roll or pitch
    (grip frames point their Z down into the part)."""
    x = T_world_frame[:3, 0].copy()
    x[2] = 0.0
    if np.linalg.norm(x) < 1e-9:
        x = np.array([1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, 0], T[:3, 2] = x, (0.0, 0.0, 1.0)
    T[:3, 1] = np.cross(T[:3, 2], x)
    T[:3, 3] = T_world_frame[:3, 3]
    return T
