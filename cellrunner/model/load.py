"""Loading cell and task files: YAML -> schema -> references, all errors located.

``load_cell`` and ``load_task`` collect every problem they find and raise one
:class:`InputError` carrying them all (one ``FILE:LINE:COL: error: ...`` line each);
warnings (e.g. angles that look like radians) are kept on the loaded object.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pydantic import ValidationError

from cellrunner.errors import Diagnostic, InputError
from cellrunner.model.cell import Cell, Fixture, Part, Tool
from cellrunner.model.checks import check_io_name, check_radians
from cellrunner.model.diagnose import diagnostics_of, known_list, unknown_name
from cellrunner.model.loaded import LoadedCell as LoadedCell  # re-exported
from cellrunner.model.loaded import LoadedTask as LoadedTask  # re-exported
from cellrunner.model.loaded import StepSpec as StepSpec  # re-exported
from cellrunner.model.references import check_task_references
from cellrunner.model.report import Report as Report  # re-exported
from cellrunner.model.robots import RobotSpec, robot_spec
from cellrunner.model.source import PathKey, file_problem, load_yaml
from cellrunner.model.step_kinds import STEP_KINDS
from cellrunner.model.task import TaskFile

if TYPE_CHECKING:
    from cellrunner.model.params import Param

_CHANNEL = re.compile(r"^(DO|CO|TO|AO|DI|CI|TI|AI)(\d+)$")
_CHANNEL_COUNT = {"DO": 8, "CO": 8, "TO": 2, "AO": 2, "DI": 8, "CI": 8, "TI": 2, "AI": 2}
_CHANNEL_HELP = "DO0-7, CO0-7, TO0-1, AO0-1 for outputs; DI0-7, CI0-7, TI0-1, AI0-1 for inputs"


# ---------------------------------------------------------------------------- cell


def load_cell(path: str | Path) -> LoadedCell:
    """Load and check a cell file; raises InputError listing every problem."""
    path = Path(path)
    source = load_yaml(path)
    report = Report(source)
    if not isinstance(source.data, dict):
        report.error((), "a cell file is a mapping with keys cell, robot, tool, io, ...")
        report.raise_if_errors()
    try:
        cell = Cell.model_validate(source.data)
    except ValidationError as exc:
        raise InputError(diagnostics_of(exc, source, Cell)) from None
    loaded = LoadedCell(cell, path, source, report.warnings)
    _check_cell(loaded, report)
    report.raise_if_errors()
    loaded.digest = _cell_digest(loaded)
    return loaded


def _cell_digest(loaded: LoadedCell) -> str:
    """The cell file's digest with the bytes of every mesh it names (a mesh edited in
    place changes the plan's key too)."""
    import hashlib

    h = hashlib.sha256(loaded.source.digest.encode())
    for file in sorted(set(_mesh_files(loaded.source.data))):
        path = loaded.resolve(file)
        h.update(str(path).encode())
        try:
            h.update(path.read_bytes())
        except OSError:
            h.update(b"missing")
    return h.hexdigest()


def _mesh_files(data: Any) -> list[str]:
    """Every ``mesh: {file: ...}`` written anywhere in a cell file's data."""
    found: list[str] = []
    if isinstance(data, dict):
        mesh = data.get("mesh")
        if isinstance(mesh, dict) and isinstance(mesh.get("file"), str):
            found.append(mesh["file"])
        for value in data.values():
            found.extend(_mesh_files(value))
    elif isinstance(data, list):
        for value in data:
            found.extend(_mesh_files(value))
    return found


def _check_cell(loaded: LoadedCell, report: Report) -> None:
    cell, spec = loaded.cell, robot_spec(loaded.cell.robot.model)
    raw = loaded.source.data
    _check_limits(cell, spec, report)
    check_radians(raw, ("robot", "home"), report)
    ranges_ok = _check_joint_range(cell, spec, report)
    where = ""
    if ranges_ok and cell.robot.joint_range is not None:
        spec, where = loaded.spec, " (robot.joint_range)"
    for i, (lo, hi, q) in enumerate(
        zip(spec.joint_min_deg, spec.joint_max_deg, cell.robot.home, strict=True)
    ):
        if not lo <= q <= hi:
            report.error(
                ("robot", "home", i),
                f"joint {i + 1} = {q:g} deg is outside [{lo:g}, {hi:g}]{where}",
            )
    for path, tool in _tools(cell):
        if tool.payload.mass > spec.payload_max_kg:
            report.error(
                path + ("payload", "mass"),
                f"{tool.payload.mass:g} kg is above the {spec.name.upper()} payload "
                f"of {spec.payload_max_kg:g} kg",
            )
    _check_io(cell, report)
    for path, tool in _tools(cell):
        _check_gripper(cell, tool, path, report)
    _check_tool_names(cell, raw, report)
    _check_names(cell, report)
    _check_frames(cell, report)
    _check_cameras(cell, report)
    for i, fixture in enumerate(cell.fixtures):
        if fixture.mesh is not None:
            problem = file_problem(loaded.resolve(fixture.mesh.file))
            if problem is not None:
                report.error(
                    ("fixtures", i, "mesh", "file"),
                    f"mesh file {fixture.mesh.file!r} {problem} (looked under {loaded.root})",
                )
    from cellrunner.model.checks import check_sim_block

    check_sim_block(cell, report)
    from cellrunner.model.checks import check_watch

    check_watch(cell, report)
    from cellrunner.model.conveyor_checks import check_conveyors

    check_conveyors(cell, report)
    from cellrunner.model.marker_checks import check_markers

    check_markers(loaded, report)
    for i, part in enumerate(cell.parts):
        if part.at not in cell.frames:
            report.error(("parts", i, "at"), unknown_name("frame", part.at, cell.frames))
    from cellrunner.model import sanity

    sanity.check_cell(loaded, report)
    for number, task_path in cell.tasks.items():
        problem = file_problem(loaded.resolve(task_path))
        if problem is not None:
            report.error(
                ("tasks", number), f"task file {task_path!r} {problem} (looked under {loaded.root})"
            )


def serve_file_warnings(loaded: LoadedCell) -> list[Diagnostic]:
    """Warnings about files ``serve`` needs that do not exist yet (shown by ``validate``
    and ``serve``; a dry-run never needs them)."""
    report = Report(loaded.source)
    opcua = loaded.cell.plc.opcua
    if opcua and opcua.users and not loaded.resolve(opcua.users).exists():
        report.warn(
            ("plc", "opcua", "users"),
            f"users file {opcua.users!r} does not exist yet; create it with 'cellrunner users add'",
        )
    return report.warnings


def _check_joint_range(cell: Cell, spec: RobotSpec, report: Report) -> bool:
    """``robot.joint_range``: each [min, max] with min < max inside the arm's own range.
    True when there is none or every range is good."""
    ranges = cell.robot.joint_range
    if ranges is None:
        return True
    ok = True
    for i, (lo, hi) in enumerate(ranges):
        hw_lo, hw_hi = spec.joint_min_deg[i], spec.joint_max_deg[i]
        if lo >= hi:
            report.error(
                ("robot", "joint_range", i),
                f"joint {i + 1} range [{lo:g}, {hi:g}]: min must be below max",
            )
            ok = False
        elif lo < hw_lo - 1e-9 or hi > hw_hi + 1e-9:
            report.error(
                ("robot", "joint_range", i),
                f"joint {i + 1} range [{lo:g}, {hi:g}] is outside the {spec.label}'s "
                f"[{hw_lo:g}, {hw_hi:g}] deg; joint_range can only narrow it",
            )
            ok = False
    return ok


def _check_limits(cell: Cell, spec: RobotSpec, report: Report) -> None:
    limits = cell.robot.limits
    model = spec.name.upper()
    if limits.joint_speed is not None:
        values = (
            limits.joint_speed if isinstance(limits.joint_speed, list) else [limits.joint_speed] * 6
        )
        for i, (v, cap) in enumerate(zip(values, spec.joint_speed_max_deg_s, strict=True)):
            if v > cap + 1e-9:
                path = ("robot", "limits", "joint_speed") + (
                    (i,) if isinstance(limits.joint_speed, list) else ()
                )
                report.error(
                    path,
                    f"{v:g} deg/s on joint {i + 1} ({_joint(i)}) is above the {model} "
                    f"controller's {cap:g} deg/s",
                )
                if not isinstance(limits.joint_speed, list):
                    break
    if limits.joint_accel is not None:
        values = (
            limits.joint_accel if isinstance(limits.joint_accel, list) else [limits.joint_accel] * 6
        )
        for i, v in enumerate(values):
            if v > spec.joint_accel_max_deg_s2 + 1e-9:
                path = ("robot", "limits", "joint_accel") + (
                    (i,) if isinstance(limits.joint_accel, list) else ()
                )
                report.error(
                    path,
                    f"{v:g} deg/s^2 is above the {model} controller's "
                    f"{spec.joint_accel_max_deg_s2:.0f} deg/s^2",
                )
                break
    if limits.tcp_speed is not None and limits.tcp_speed > spec.tcp_speed_max_mps + 1e-9:
        slip = (
            f"; did you mean {limits.tcp_speed:g} mm/s = {limits.tcp_speed / 1000:g} m/s? (write "
            f"'{limits.tcp_speed:g} mm/s')"
            if limits.tcp_speed / 1000 <= spec.tcp_speed_max_mps
            else ""
        )
        report.error(
            ("robot", "limits", "tcp_speed"),
            f"{limits.tcp_speed:g} m/s is above the {model} "
            f"controller's {spec.tcp_speed_max_mps:g} m/s{slip}",
        )


def _joint(i: int) -> str:
    from cellrunner.model.robots import JOINT_NAMES

    return JOINT_NAMES[i]


def _check_io(cell: Cell, report: Report) -> None:
    used: dict[str, str] = {}
    for side, table in (("outputs", cell.io.outputs), ("inputs", cell.io.inputs)):
        for name, channel in table.items():
            m = _CHANNEL.match(channel)
            want_out = side == "outputs"
            if not m:
                report.error(
                    ("io", side, name), f"bad channel {channel!r} for {name!r}; use {_CHANNEL_HELP}"
                )
                continue
            prefix, number = m.group(1), int(m.group(2))
            if (prefix[1] == "O") != want_out:
                report.error(
                    ("io", side, name),
                    f"channel {channel!r} is an {'input' if want_out else 'output'}; "
                    f"{side} use {'DO, CO, TO, AO' if want_out else 'DI, CI, TI, AI'}",
                )
            elif number >= _CHANNEL_COUNT[prefix]:
                report.error(
                    ("io", side, name),
                    f"channel {channel!r} does not exist; "
                    f"{prefix} goes from {prefix}0 to {prefix}{_CHANNEL_COUNT[prefix] - 1}",
                )
            elif channel in used:
                report.error(
                    ("io", side, name), f"channel {channel} is already used by {used[channel]!r}"
                )
            used[channel] = name
    both = set(cell.io.outputs) & set(cell.io.inputs)
    for name in sorted(both):
        report.error(
            ("io", "inputs", name), f"name {name!r} is both an output and an input", at_key=True
        )


def _tools(cell: Cell) -> list[tuple[PathKey, Any]]:
    """Every tool of the cell with its path in the file (``tools.NAME`` or ``tool``)."""
    if cell.tools:
        return [(("tools", name), tool) for name, tool in cell.tools.items()]
    return [(("tool",), cell.tool)]


def _check_gripper(cell: Cell, tool: Tool, path: PathKey, report: Report) -> None:
    g = tool.gripper
    if g is None:
        return
    base = path + ("gripper",)
    if g.kind == "io" and g.close is None:
        report.error(base, "an io gripper needs 'close: {output, value}'")
    if g.kind == "vacuum":
        for key, example in (
            ("suction", "suction: {output, value}"),
            ("vacuum_ok", "vacuum_ok: INPUT"),
            ("cups", "cups: [{xyz, radius}]"),
            ("holding_force", "holding_force: N"),
        ):
            if not getattr(g, key):
                report.error(base, f"a vacuum gripper needs '{example}'")
        if g.suction is not None:
            check_io_name(cell, g.suction.output, "outputs", base + ("suction", "output"), report)
        if g.vacuum_ok is not None:
            check_io_name(cell, g.vacuum_ok, "inputs", base + ("vacuum_ok",), report)
        if g.blow_off is not None:
            check_io_name(cell, g.blow_off.output, "outputs", base + ("blow_off", "output"), report)
    for key in ("close", "open"):
        ov = getattr(g, key)
        if ov is not None:
            check_io_name(cell, ov.output, "outputs", base + (key, "output"), report)
    for key in ("closed_sensor", "open_sensor"):
        name = getattr(g, key)
        if name is not None:
            check_io_name(cell, name, "inputs", base + (key,), report)


def _check_tool_names(cell: Cell, raw: Any, report: Report) -> None:
    """``robot.tool`` names one of ``tools``; a tool changer racks every tool."""
    names = list(cell.tools)
    if cell.tools:
        if isinstance(raw, dict) and "tool" in raw:  # (the model copies the mounted one into tool)
            report.error(("tool",), "give either 'tool:' or 'tools:', not both", at_key=True)
        if cell.robot.tool is None:
            report.error(
                ("robot",),
                f"with 'tools:', robot.tool names the tool mounted at start; "
                f"known: {known_list(names)}",
            )
        elif cell.robot.tool not in cell.tools:
            report.error(("robot", "tool"), unknown_name("tool", cell.robot.tool, names))
    elif cell.robot.tool is not None:
        report.error(
            ("robot", "tool"),
            f"robot.tool {cell.robot.tool!r} names a tool but the cell has no "
            "'tools:' (give tools: {NAME: TOOL})",
        )
    changer = cell.tool_changer
    if changer is None:
        return
    base = ("tool_changer",)
    check_io_name(cell, changer.lock, "outputs", base + ("lock",), report)
    if changer.locked is not None:
        check_io_name(cell, changer.locked, "inputs", base + ("locked",), report)
    for name, frame in changer.rack.items():
        if name not in cell.tools:
            report.error(base + ("rack", name), unknown_name("tool", name, names), at_key=True)
        if frame not in cell.frames:
            report.error(base + ("rack", name), unknown_name("frame", frame, cell.frames))
    missing = [n for n in names if n not in changer.rack]
    if missing:
        report.error(
            base + ("rack",),
            f"the rack has no place for tool(s) {', '.join(map(repr, missing))}; "
            f"give each a frame: rack: {{{', '.join(f'{n}: FRAME' for n in names)}}}",
        )


def _check_names(cell: Cell, report: Report) -> None:
    seen: dict[str, str] = {}
    named: tuple[tuple[str, Sequence[Fixture | Part]], ...] = (
        ("fixture", cell.fixtures),
        ("part", cell.parts),
    )
    for kind, items in named:
        for i, item in enumerate(items):
            key = f"{kind}s"
            if item.name in seen:
                report.error(
                    (key, i, "name"), f"name {item.name!r} is already used by a {seen[item.name]}"
                )
            seen[item.name] = kind
    for name in cell.frames:
        if name in ("home", "world"):
            report.error(
                ("frames", name), f"{name!r} is reserved and cannot name a frame", at_key=True
            )


def _check_frames(cell: Cell, report: Report) -> None:
    for name, frame in cell.frames.items():
        if frame.parent != "world" and frame.parent not in cell.frames:
            report.error(
                ("frames", name, "parent"),
                unknown_name("parent frame", frame.parent, ["world", *cell.frames]),
            )
            continue
        seen, cur = {name}, frame.parent
        while cur != "world" and cur in cell.frames:
            if cur in seen:
                report.error(
                    ("frames", name, "parent"),
                    f"frame {name!r} is its own ancestor (cycle through {cur!r})",
                )
                break
            seen.add(cur)
            cur = cell.frames[cur].parent
        check_radians(report.source.data, ("frames", name, "rpy"), report)


def _check_cameras(cell: Cell, report: Report) -> None:
    """Camera and board mounts name world, flange or a frame; a frame cannot be 'flange'."""
    known = ["world", "flange", *cell.frames]
    if "flange" in cell.frames:
        report.error(
            ("frames", "flange"),
            "'flange' is reserved (camera mounts) and cannot name a frame",
            at_key=True,
        )
    for name, camera in cell.cameras.items():
        if camera.mount not in known:
            report.error(("cameras", name, "mount"), unknown_name("mount", camera.mount, known))
        if camera.board is not None and camera.board.mount not in known:
            report.error(
                ("cameras", name, "board", "mount"),
                unknown_name("mount", camera.board.mount, known),
            )


# ---------------------------------------------------------------------------- task


def load_task(path: str | Path, cell: LoadedCell) -> LoadedTask:
    """Load a task file and check it against ``cell``; raises InputError listing every
    problem."""
    path = Path(path)
    source = load_yaml(path)
    report = Report(source)
    if not isinstance(source.data, dict):
        report.error((), "a task file is a mapping with keys task, params, steps")
        report.raise_if_errors()
    try:
        header = TaskFile.model_validate(source.data)
    except ValidationError as exc:
        report.errors.extend(diagnostics_of(exc, source, TaskFile))
        # keep going with the steps so that all errors are reported at once
        steps_raw = source.data.get("steps") if isinstance(source.data.get("steps"), list) else []
        _parse_steps(steps_raw, ("steps",), report, allow_macros=True)
        report.raise_if_errors()
        raise AssertionError("unreachable") from exc  # pragma: no cover
    steps = _parse_steps(header.steps, ("steps",), report, allow_macros=True, params=header.params)
    on_error = _parse_steps(
        header.on_error, ("on_error",), report, allow_macros=False, params=header.params
    )
    loaded = LoadedTask(header, path, source, steps, report.warnings, on_error)
    if not report.errors:
        check_task_references(loaded, cell, report)
        from cellrunner.model import sanity

        sanity.check_task(loaded, cell, report)
    report.raise_if_errors()
    return loaded


def _parse_steps(
    raw: list[Any],
    base: PathKey,
    report: Report,
    *,
    allow_macros: bool,
    params: dict[str, Param] | None = None,
) -> list[StepSpec]:
    out = []
    for i, item in enumerate(raw):
        spec = _parse_step(item, base + (i,), report, allow_macros, params or {})
        if spec is not None:
            out.append(spec)
    return out


def _parse_step(
    item: Any, path: PathKey, report: Report, allow_macros: bool, params: dict[str, Param]
) -> StepSpec | None:
    written = [STEP_KINDS[k] for k in STEP_KINDS.written()]
    known = [k.name for k in written if allow_macros or not k.top_level_only]
    top_level_only = [k.name for k in written if k.top_level_only]
    if isinstance(item, str):
        item = {item: None}
    if not isinstance(item, dict) or len(item) != 1:
        report.error(
            path,
            f"a step is one {{KIND: ARGS}} mapping or a bare KIND; known kinds: "
            f"{known_list(known)}",
        )
        return None
    kind, args = next(iter(item.items()))
    if kind not in known:
        hint = (
            ""
            if kind not in top_level_only
            else (
                " (align belongs in the task's steps)"
                if kind == "align"
                else " (on_error takes primitive steps)"
                if path[0] == "on_error"
                else " (pick and place cannot be nested)"
            )
        )
        report.error(path + (kind,), unknown_name("step", kind, known) + hint, at_key=True)
        return None
    model = STEP_KINDS[kind].args
    assert model is not None  # a kind a file may write
    raw = STEP_KINDS[kind].widen(args)
    from cellrunner.model.params import substitute

    refs: set[str] = set()
    try:
        # a float param stands for a quantity: its default, min and max must all read there
        parsed = None
        for bound in ("default", "min", "max"):
            values = {
                n: getattr(p, bound) for n, p in params.items() if getattr(p, bound) is not None
            }
            args_b, refs = substitute(raw, params, values)
            checked = model.model_validate(args_b)
            parsed = parsed or checked
            if not refs:
                break
    except ValidationError as exc:
        report.errors.extend(diagnostics_of(exc, report.source, model, prefix=path + (kind,)))
        return None
    spec = StepSpec(kind, parsed, path + (kind,), raw=raw if refs else None, refs=frozenset(refs))
    retry = getattr(parsed, "retry", None)
    if retry is not None:  # a pick's retry.between
        spec.between = _parse_steps(
            retry.between,
            path + (kind, "retry", "between"),
            report,
            allow_macros=False,
            params=params,
        )
    return spec
