"""The twin's description of a loaded cell file (the twin itself never reads YAML)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.model.cell import Gripper
from cellrunner.model.expand import frame_pose
from cellrunner.model.gripper import gripper_channels, part_center_depth_m
from cellrunner.model.load import LoadedCell, LoadedTask
from cellrunner.model.step import StepKind
from cellrunner.model.watch import INJECTED_BOX_M

if TYPE_CHECKING:
    from cellrunner.sim.description import TwinDescription
    from cellrunner.sim.input_rules import InputRuleDescription

#: copies of the fed part (``sim: feed``) the twin keeps parked; when all are out, the
#: oldest comes back
FEED_COPIES = 12

#: a marker's sheet stands this far out of the face it is printed on (m): coplanar faces
#: would flicker into each other in the picture
PRINT_LIFT_M = 0.0003
#: frame -> the gripper of the tool that picks parts there
Picks = dict[str, Gripper | None]

if TYPE_CHECKING:
    from cellrunner.model.cell import Cell, Gripper, Part, Tool
    from cellrunner.model.geometry import Shape
    from cellrunner.sim.cameras import CameraDescription, MarkerDescription
    from cellrunner.sim.description import GripperDescription, PartDescription, TwinDescription
    from cellrunner.sim.input_rules import InputRuleDescription
    from cellrunner.sim.tool_changer import ToolChangerDescription
    from cellrunner.sim.vacuum import VacuumDescription


def description_of(
    loaded: LoadedCell,
    tasks: tuple[LoadedTask, ...] = (),
    feed: tuple[str, str] | None = None,
    feed_copies: int = FEED_COPIES,
) -> TwinDescription:
    """A :class:`TwinDescription` of ``loaded``: arm, mount, tool, gripper, fixtures, parts, IO.

    With ``tools:`` and a tool changer every tool is built (each enabled while mounted):
    the jaws of the first tool with jaws, the cups of the first vacuum tool. A part then
    lies as the tool that picks it at its frame holds it (jaws: centred; cups: top face),
    found in ``tasks`` (loaded tasks) and the cell's own ``tasks:``. ``feed`` (part,
    frame; default the cell's ``sim: feed``) adds ``feed_copies`` copies of the part to
    be fed there before each job (:mod:`.feed`)."""
    from cellrunner.sim.description import TwinDescription
    from cellrunner.sim.feed import with_rehearsal_parts
    from cellrunner.sim.press_fits import press_fit_forces
    from cellrunner.sim.rigid_contacts import contact_fixtures

    c = loaded.cell
    outputs, inputs = c.io.outputs, c.io.inputs
    io_outputs, io_inputs = (
        list(dict.fromkeys(outputs.values())),
        list(dict.fromkeys(inputs.values())),
    )
    changer = (
        _changer(loaded, io_outputs, io_inputs) if c.tools and c.tool_changer is not None else None
    )
    tools = list(c.tools.values()) if changer is not None else [c.tool]
    suction = next((t for t in tools if t.gripper is not None and t.gripper.kind == "vacuum"), None)
    jaws = [t for t in tools if t.gripper is not None and t.gripper.kind != "vacuum"]
    jaws.sort(key=lambda t: t is not c.tool)  # the mounted tool's jaws first
    gripper = _jaws(jaws[0], c, io_outputs, io_inputs) if jaws else None
    vacuum = _cups(suction, c) if suction is not None else None
    every_task = _cell_tasks(loaded, tasks)
    picks: Picks = _picking_grippers(loaded, every_task) if c.tools else {}
    parts = [_part(loaded, p, picks.get(p.at, c.tool.gripper)) for p in c.parts]
    desc = TwinDescription(
        spec=loaded.spec,
        T_world_base=c.robot.mount.matrix(),
        T_flange_tcp=c.tool.tcp.matrix(),
        q_home_rad=tuple(np.radians(c.robot.home)),
        tool_geometry=tuple(loaded.tool_shapes()) if changer is None else (),
        payload_mass_kg=max(c.tool.payload.mass, 0.1),
        payload_cog_m=c.tool.payload.cog_m,
        gripper=gripper,
        vacuum=vacuum,
        tool_changer=changer,
        fixtures=tuple(loaded.fixture_shapes()),
        parts=tuple(parts),
        io_outputs=tuple(io_outputs),
        io_inputs=tuple(io_inputs),
        input_rules=_input_rules(loaded, picks),
        cameras=_cameras(loaded),
        markers=_markers(loaded, every_task, parts),
        intruders=_intruders(loaded),
        depth=tuple(
            (name, cam.depth.range[0], cam.depth.range[1], cam.depth.rate)
            for name, cam in c.cameras.items()
            if cam.depth is not None
        ),
        depth_noise_m=c.sim.depth_noise if c.sim is not None else 0.0,
        rigid_fixtures=contact_fixtures(every_task),
        press_fits=press_fit_forces(every_task),
        name=c.cell,
    )
    shifts: dict[str, np.ndarray] = {}
    if c.conveyors:  # the twin's belts carry the parts lying at their frames
        desc, shifts = _on_belts(loaded, desc)
    if feed is None and c.sim is not None and c.sim.feed is not None:
        feed = (c.sim.feed.part, c.sim.feed.frame(c.conveyors))
    if feed is None:
        return desc
    part = next(p for p in c.parts if p.name == feed[0])
    shape = part.to_shape(loaded.resolve)
    T_fed = _part_pose(frame_pose(c, feed[1]), picks.get(feed[1], c.tool.gripper), shape)
    if shifts:
        from cellrunner.sim.belts import upstream

        T_fed = upstream(T_fed, _belt_frames(loaded), shifts)
    desc = with_rehearsal_parts(desc, (part.name, T_fed), feed_copies)
    return _timed_feed(loaded, desc)


def _timed_feed(loaded: LoadedCell, desc: TwinDescription) -> TwinDescription:
    """``desc`` whose feed comes by time when the cell's ``sim: feed`` names a straight
    conveyor and ``every`` (:mod:`.feed`)."""
    import dataclasses

    sim = loaded.cell.sim
    feed = sim.feed if sim is not None else None
    if desc.feed is None or feed is None or feed.conveyor is None or feed.every is None:
        return desc
    belt = next((b for b in desc.belts if b.name == feed.conveyor), None)
    if belt is None or belt.arc is not None:
        return desc  # a round table's feed comes before each job
    timed = dataclasses.replace(
        desc.feed,
        every_s=float(feed.every),
        jitter_m=float(feed.jitter),
        along=tuple(float(v) for v in belt.direction),
        speed_mps=float(belt.speed_mps),
    )
    return dataclasses.replace(desc, feed=timed)


def _belt_frames(loaded: LoadedCell) -> dict[str, np.ndarray]:
    c = loaded.cell
    return {name: frame_pose(c, conv.frame) for name, conv in c.conveyors.items()}


def _on_belts(
    loaded: LoadedCell, desc: TwinDescription
) -> tuple[TwinDescription, dict[str, np.ndarray]]:
    """``desc`` with the twin's belts and photo-eyes, each part lying at a belt's frame
    put upstream of its eye (:mod:`.belts`); and the shifts that do that."""
    import dataclasses

    from cellrunner.sim.belts import belts_of_cell, upstream

    c = loaded.cell
    frames = _belt_frames(loaded)
    belts, eyes, shifts = belts_of_cell(dict(c.conveyors), dict(c.io.inputs), frames)
    parts = tuple(
        dataclasses.replace(p, T_world_part=upstream(p.T_world_part, frames, shifts))
        for p in desc.parts
    )
    out = dataclasses.replace(
        desc, belts=belts, parts=parts, presence_sensors=(*desc.presence_sensors, *eyes)
    )
    return out, shifts


def rehearsal_description(
    loaded: LoadedCell, task: LoadedTask, params: dict[str, Any], jobs: int = 1
) -> TwinDescription:
    """The twin of a ``dry-run`` of ``task`` from ``params`` (resolved), ``jobs`` jobs in
    a row (SPEC section 12): the cell with a part on every earlier slot of each place
    pattern, and for several jobs a part fed before each (the cell's ``sim: feed``, else
    the part the task picks first, at its frame)."""
    from cellrunner.sim.feed import earlier_slots, feed_of, with_rehearsal_parts

    desc = description_of(loaded, (task,), feed_of(loaded, task, jobs > 1), max(FEED_COPIES, jobs))
    placed = earlier_slots(loaded, task, params, desc)
    return with_rehearsal_parts(desc, placed=placed) if placed else desc


def _markers(
    loaded: LoadedCell, tasks: list[LoadedTask], parts: list[PartDescription]
) -> tuple[MarkerDescription, ...]:
    """The markers where the cell file puts them (SPEC section 13): each part's and
    fixture's ``markers:``; and an align's inline marker (in ``tasks``: the given and
    the cell's own), which means a marker on the part at the frame it aligns, where its
    ``pose`` puts it in that frame, moved with the part's ``offset``. An align that names
    a marker by id prints nothing: the marker is where its carrier has it."""
    from cellrunner.model.align import aligned_frame
    from cellrunner.model.marker import Marker
    from cellrunner.sim.cameras import MarkerDescription
    from cellrunner.vision.marker import picture, printed_size_m

    c = loaded.cell
    out: dict[tuple[str, str, int], MarkerDescription] = {}

    def printed(carrier: str, marker: Marker, T_carrier_marker: np.ndarray) -> None:
        key = (carrier, marker.dictionary, marker.id)
        if key in out:
            return
        T = np.array(T_carrier_marker, float)
        T[:3, 3] += T[:3, 2] * PRINT_LIFT_M
        name = carrier or "fixture"
        out[key] = MarkerDescription(
            carrier, f"{name}-{marker.id}", T, printed_size_m(marker), picture(marker)
        )

    for part in c.parts:
        for marker in part.markers:
            printed(part.name, marker, marker.pose.matrix())
    for fixture in c.fixtures:
        for marker in fixture.markers:
            printed("", marker, fixture.matrix() @ marker.pose.matrix())
    for task in tasks:
        for i, spec in enumerate(task.steps):
            frame = aligned_frame(task.steps, i) if spec.kind == StepKind.ALIGN else None
            if frame is None or not isinstance(spec.args.marker, Marker):
                continue
            inline: Marker = spec.args.marker
            for part, described in zip(c.parts, parts, strict=True):
                if part.at != frame:
                    continue
                T_world_grip = frame_pose(c, frame)
                if part.offset is not None:
                    T_world_grip = T_world_grip @ part.offset.matrix()
                T_part_marker = (
                    np.linalg.inv(described.T_world_part) @ T_world_grip @ inline.pose.matrix()
                )
                printed(part.name, inline, T_part_marker)
    return tuple(out.values())


def _cell_tasks(loaded: LoadedCell, tasks: tuple[LoadedTask, ...]) -> list[LoadedTask]:
    """``tasks`` and the cell's own ``tasks:``, each file loaded once: one of ``tasks``
    is not read again, and a task file that does not load is skipped."""
    from cellrunner.errors import CellrunnerError
    from cellrunner.model.load import load_task

    found = list(tasks)
    seen = {t.path.resolve() for t in tasks}
    for path in loaded.cell.tasks.values():
        resolved = Path(loaded.resolve(path)).resolve()
        if resolved in seen:
            continue
        seen.add(resolved)
        try:
            found.append(load_task(resolved, loaded))
        except (CellrunnerError, OSError):
            continue
    return found


def _intruders(loaded: LoadedCell) -> tuple[Any, ...]:
    """The cell's ``sim: intruders``, and in a watched cell the box an injection drops."""
    from cellrunner.model.geometry import Box, Cylinder
    from cellrunner.sim.depth import IntruderDescription

    c = loaded.cell
    out = []
    for i in c.sim.intruders if c.sim is not None else ():
        T = frame_pose(c, i.at) if i.at is not None else i.pose.matrix()  # type: ignore[union-attr]
        shape = (
            Box((i.box.size[0], i.box.size[1], i.box.size[2]))
            if i.box is not None
            else Cylinder(i.cylinder.radius, i.cylinder.length)  # type: ignore[union-attr]
        )
        out.append(IntruderDescription(i.name, shape, T, i.appear, i.leave))
    if c.watch is not None:
        out.append(IntruderDescription("intrusion", Box(INJECTED_BOX_M), np.eye(4), on_inject=True))
    return tuple(out)


def _cameras(loaded: LoadedCell) -> tuple[CameraDescription, ...]:
    if not loaded.cell.cameras:
        return ()
    from cellrunner.sim.cameras import describe_cameras

    return describe_cameras(loaded)


def _part(loaded: LoadedCell, part: Part, gripper: Gripper | None) -> PartDescription:
    """A part where a TCP at its frame grips it, moved by its twin-only ``offset``."""
    from cellrunner.sim.description import PartDescription

    T_world_frame = frame_pose(loaded.cell, part.at)
    T_world_grip = T_world_frame
    if part.offset is not None:
        T_world_grip = T_world_grip @ part.offset.matrix()
    shape = part.to_shape(loaded.resolve)
    return PartDescription(
        part.name,
        shape,
        part.mass,
        _part_pose(T_world_grip, gripper, shape),
        part.friction,
        np.linalg.solve(T_world_frame, _part_pose(T_world_frame, gripper, shape)),
    )


def _input_rules(loaded: LoadedCell, picks: Picks) -> tuple[InputRuleDescription, ...]:
    """The ``sim: inputs`` rules in channels and world metres."""
    from cellrunner.sim.input_rules import InputRuleDescription

    cell = loaded.cell
    if cell.sim is None:
        return ()
    out = []
    for name, rule in cell.sim.inputs.items():
        channel = cell.io.inputs[name]
        if rule.part_at is not None:
            point = _part_at_point(loaded, rule.part_at, picks)
            out.append(
                InputRuleDescription(
                    channel,
                    "part_at",
                    point_world_m=point,
                    within_m=rule.within,
                    invert=rule.invert,
                )
            )
        else:
            kind = "follows" if rule.follows is not None else "pulse_after"
            source = rule.follows or rule.pulse_after
            assert source is not None  # a rule is part_at, follows or pulse_after (validated)
            output = cell.io.outputs[source]
            out.append(
                InputRuleDescription(
                    channel,
                    kind,
                    output=output,
                    delay_s=rule.delay,
                    width_s=rule.width,
                    invert=rule.invert,
                )
            )
    return tuple(out)


def _picking_grippers(loaded: LoadedCell, tasks: list[LoadedTask]) -> Picks:
    """frame -> the gripper of the tool mounted where a task picks at that frame (the
    tasks' steps with their params' defaults)."""
    from cellrunner.errors import CellrunnerError
    from cellrunner.model.expand import resolve_params
    from cellrunner.model.job_steps import job_steps

    c = loaded.cell
    picks: Picks = {}
    for task in tasks:
        try:
            steps = job_steps(task, c, resolve_params(task.task, {}))
        except (CellrunnerError, ValueError):
            continue
        tool = c.robot.tool
        for step in steps:
            if step.kind == StepKind.TOOL_LOCK:
                tool = step.extra["tool"]
            elif step.kind == StepKind.GRIP and isinstance(step.extra.get("part_at"), str):
                picks.setdefault(step.extra["part_at"], c.tools[tool].gripper if tool else None)
    return picks


def _part_at_point(loaded: LoadedCell, frame: str, picks: Picks) -> tuple[float, float, float]:
    """Where the centre of a part lying at ``frame`` is, as parts ``at:`` a frame lie: the
    frame itself for jaws, half the part's height under it for suction (the frame is the
    top face). The part that spawns at the frame is measured, else the cell's first part."""
    cell = loaded.cell
    x, y, z = (float(v) for v in frame_pose(cell, frame)[:3, 3])
    part = next((p for p in cell.parts if p.at == frame), cell.parts[0] if cell.parts else None)
    if part is not None:
        gripper = picks.get(part.at, cell.tool.gripper)
        z -= part_center_depth_m(gripper, part.to_shape(loaded.resolve))
    return (x, y, z)


def _jaws(
    tool: Tool, cell: Cell, io_outputs: list[str], io_inputs: list[str]
) -> GripperDescription:
    from cellrunner.sim.description import GripperDescription

    g = tool.gripper
    assert g is not None  # called for tools with jaws
    close, _, sensor = gripper_channels(g, cell.io.outputs, cell.io.inputs)
    assert close is not None  # jaws close on an output (validated)
    io_outputs += [close[0]] if close[0] not in io_outputs else []
    io_inputs += [sensor] if sensor and sensor not in io_inputs else []
    return GripperDescription(
        stroke_m=g.stroke,
        jaw_speed_mps=g.stroke / 2 / g.close_time,
        close_output=close[0],
        close_value=close[1],
        closed_sensor_input=sensor,
        open_sensor_input=cell.io.inputs.get(g.open_sensor) if g.open_sensor else None,
        T_flange_tcp=tool.tcp.matrix(),
    )


def _cups(tool: Tool, cell: Cell) -> VacuumDescription:
    from cellrunner.sim.vacuum import VacuumDescription

    g = tool.gripper
    assert g is not None  # called for a vacuum tool
    close, _, sensor = gripper_channels(g, cell.io.outputs, cell.io.inputs)
    assert close is not None  # suction switches on through an output (validated)
    return VacuumDescription(
        cups=tuple(((cup.xyz[0], cup.xyz[1], cup.xyz[2]), cup.radius) for cup in g.cups),
        suction_output=close[0],
        suction_value=close[1],
        vacuum_ok_input=sensor,
        blow_off_output=cell.io.outputs[g.blow_off.output] if g.blow_off else None,
        holding_force_N=g.holding_force or 100.0,
        T_flange_tcp=tool.tcp.matrix(),
    )


def _changer(
    loaded: LoadedCell, io_outputs: list[str], io_inputs: list[str]
) -> ToolChangerDescription:
    from cellrunner.sim.tool_changer import ChangerTool, ToolChangerDescription

    c = loaded.cell
    changer = c.tool_changer
    assert changer is not None and c.robot.tool is not None  # called for a tool changer
    mounted = c.robot.tool
    tools = []
    for name, tool in c.tools.items():
        g = tool.gripper
        kind = None if g is None else "vacuum" if g.kind == "vacuum" else "jaws"
        shapes = loaded.tool_shapes(tool)
        tools.append(
            ChangerTool(
                name,
                tool.tcp.matrix(),
                tuple(shapes),
                max(tool.payload.mass, 0.1),
                tool.payload.cog_m,
                kind,
                frame_pose(c, changer.rack[name]),
                _jaws(tool, c, io_outputs, io_inputs) if kind == "jaws" else None,
            )
        )
    return ToolChangerDescription(
        c.io.outputs[changer.lock],
        c.io.inputs[changer.locked] if changer.locked else None,
        tuple(tools),
        mounted,
    )


def _part_pose(T_world_grip: np.ndarray, gripper: Gripper | None, shape: Shape) -> np.ndarray:
    """A part lies upright where a TCP at ``T_world_grip`` grips it (the model's rule)."""
    from cellrunner.model.part_pose import part_pose

    return part_pose(T_world_grip, gripper, shape)
