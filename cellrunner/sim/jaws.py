"""The two-finger jaws of the twin (:class:`~.description.GripperDescription`): force
drives that close while the close output has its close value, and the proximity switches
that report a closed grip and open jaws."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    from cellrunner.sim.description import GripperDescription, TwinDescription
    from cellrunner.sim.faults import GripFaults
    from cellrunner.sim.model_ids import ModelIds


class JawWorld(Protocol):
    """What the jaws read and drive in the twin (:class:`~cellrunner.sim.world.SimWorld`)."""

    description: TwinDescription
    data: Any
    grip_faults: GripFaults
    outputs: dict[str, float | bool]

    @property
    def ids(self) -> ModelIds: ...


JAW_REST_SPEED_MPS = 0.005


class Jaws:
    """The jaws of one built :class:`SimWorld`, as the world's description has them now
    (a tool change swaps in the mounted tool's). ``enabled``: mounted and in use (a tool
    change turns them off); ``closing``: commanded closed at the last :meth:`drive`."""

    def __init__(self, world: JawWorld) -> None:
        ids = world.ids
        self.world = world
        self.enabled = True
        self.closing = False
        self.driven = False  # drive forces written to ctrl; False: write them again
        self._adr = [int(a) for a in ids.jaw_qpos]
        self._dof = [int(a) for a in ids.jaw_dof]
        self._act = [int(a) for a in ids.jaw_act]

    @property
    def qpos_adr(self) -> tuple[int, int]:
        """Where the two slides sit in qpos."""
        a, b = self._adr
        return a, b

    @property
    def dof_adr(self) -> tuple[int, int]:
        """Where the two slides sit in qvel."""
        a, b = self._dof
        return a, b

    @property
    def gripper(self) -> GripperDescription:
        g = self.world.description.gripper
        assert g is not None  # the world builds jaws only for a description with a gripper
        return g

    def channels(self) -> set[str]:
        """The inputs the jaw switches drive."""
        g = self.gripper
        return {c for c in (g.closed_sensor_input, g.open_sensor_input) if c}

    def drive(self) -> None:
        """Follow the close output (before the physics step)."""
        w, g = self.world, self.gripper
        closing = self.enabled and w.outputs.get(g.close_output) == g.close_value
        if closing == self.closing and self.driven:
            return  # the drive forces already in ctrl stay
        if closing and not self.closing:
            w.grip_faults.jaws_closing()
        self.closing = closing
        self.driven = True
        speed = g.grip_force_N if closing else -g.grip_force_N
        ctrl = w.data.ctrl
        for a in self._act:
            ctrl[a] = speed  # a force (N): the drives are force actuators

    def gap_m(self) -> float:
        """Distance between the finger pads (m); stroke when open, 0 when fully closed."""
        qpos = self.world.data.qpos
        a, b = self._adr
        return float(self.gripper.stroke_m - (qpos.item(a) + qpos.item(b)))

    def update_inputs(self, inputs: dict[str, float | bool]) -> None:
        """The switches' readings after the physics step."""
        g, data = self.gripper, self.world.data
        qpos, qvel = data.qpos.item, data.qvel.item  # Python floats, not numpy scalars
        a, b = self._adr
        gap = g.stroke_m - (qpos(a) + qpos(b))
        va, vb = self._dof
        resting = max(abs(qvel(va)), abs(qvel(vb))) < JAW_REST_SPEED_MPS
        was = bool(inputs[g.closed_sensor_input]) if g.closed_sensor_input else False
        closed, opened = switch_readings(g, gap, resting, self.closing, was)
        if g.closed_sensor_input:
            inputs[g.closed_sensor_input] = bool(closed)
        if g.open_sensor_input:
            inputs[g.open_sensor_input] = bool(opened)


def switch_readings(
    gripper: GripperDescription, gap_m: Any, resting: Any, closing: bool, was_closed: bool
) -> tuple[Any, Any]:
    """The (closed, open) switches' readings for a jaw gap (m) and whether the jaws are
    at rest, on floats or on arrays of periods alike (the look-ahead reads many periods
    with the very comparisons the twin makes each period). The closed switch comes on
    once the jaws came to rest on something, then reads their position only: jaws that
    shake on a held part (a stop, a jerk) keep it on."""
    lo = gripper.sensor_min_gap_m
    hi = gripper.stroke_m - lo
    closed = closing & (resting | was_closed) & (lo <= gap_m) & (gap_m <= hi)
    return closed, gap_m >= hi
