"""Many periods of a planned motion in one call: the physics of the next set-points runs
in C (``mujoco.rollout``) on a scratch copy of the twin, and the twin takes the periods
over only as far as nothing would have happened in them that the per-period step reacts
to.

Per period the twin judges contacts (:mod:`.contacts`), keeps where a held part sits,
and updates its inputs. A look-ahead records, for every period, what those judgements
read (contact counts, part positions, the jaws' joints, the wrist sensor's frame) as
sensors of the compiled model (:mod:`.mjcf`), and finds the first period where any of
them would differ from a plain motion: a contact on the arm, tool or pads (other than
the held part between both pads), the held part touching anything else, an input
changing. The twin takes over only the periods before it, stepped exactly as
:meth:`SimWorld.step_period` steps them (same servo inputs, same MuJoCo calls, state
and warm start carried over), so the per-period path then meets that first period with
the very state it would have had.

Only plain periods are looked ahead: suction cups idle (suction off, nothing held), a
tool changer steady (its lock output agreeing with the mount, or off with the tool away
from its rack place: the look-ahead ends where the TCP comes near it), no armed or
running grip fault, no stop ramp, safety normal. Anything else returns None and the
caller steps period by period.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.model.robot_state import Safety
from cellrunner.sim.jaws import JAW_REST_SPEED_MPS, switch_readings

if TYPE_CHECKING:
    from cellrunner.sim.world import SimWorld


@dataclass
class Preview:
    """The next periods of a motion as the twin would measure them, before the twin
    takes them over (:func:`commit`).

    ``quiet``: how many leading periods the twin itself would pass through without
    reacting (no contact verdict, no input change); rows ``0..quiet-1`` of ``time_s``
    (s), ``q_rad``, ``wrench_N`` (base axes, as :meth:`WristSensor.wrench` reads it)
    are those periods' measurements."""

    quiet: int
    time_s: np.ndarray
    q_rad: np.ndarray
    # the rollout's work, for commit (and the wrench, computed when first asked for); the
    # rolled-out data itself stays in the look-ahead's scratch until the next preview
    _ahead: Lookahead
    _sensordata: np.ndarray
    _state0: np.ndarray
    _warm0: np.ndarray
    _control: np.ndarray
    _q_ref: np.ndarray
    _qd_ref: np.ndarray
    #: a hold's set-point (the very arrays the twin holds), None for a motion
    _ends: tuple[np.ndarray, np.ndarray] | None = None

    @cached_property
    def wrench_N(self) -> np.ndarray:
        """The wrist wrench each period (N, N m, base axes, less the zeroing offset);
        most look-aheads never read it (it is computed on first use)."""
        return self._ahead._wrench(self._sensordata)

    @property
    def holds(self) -> bool:
        """Whether the set-point stays where it was (no motion streams)."""
        return self._ends is not None

    @property
    def periods(self) -> int:
        """How many periods were rolled out (the quiet ones and any after them)."""
        return len(self.time_s)


class Lookahead:
    """Look-aheads on one built :class:`SimWorld` (a scratch MjData and index tables)."""

    def __init__(self, world: SimWorld) -> None:
        mj = world.mujoco
        m = world.model
        self.world = world
        self._mj = mj
        self._rollout = _rollout_module()
        self._scratch = mj.MjData(m)
        self._full = int(mj.mjtState.mjSTATE_FULLPHYSICS)
        self._user = int(mj.mjtState.mjSTATE_USER)
        self._nstate = mj.mj_stateSize(m, self._full)
        self._nuser = mj.mj_stateSize(m, self._user)
        # where ctrl sits in a mjSTATE_USER vector: it comes first
        self._ctrl0 = 0
        ids = world.ids
        adr = m.sensor_adr

        def sensor(name: str) -> int:
            try:
                return int(adr[m.sensor(name).id])
            except KeyError:
                return -1

        self._s_arm = sensor("ahead:arm")
        self._s_pad = (sensor("ahead:pad_a"), sensor("ahead:pad_b"))
        self._s_part = sensor("ahead:part")
        self._sensor_id = {
            n: m.sensor(n).id
            for n in ("ahead:pad_a", "ahead:pad_b", "ahead:part")
            if sensor(n) >= 0
        }
        self._s_ft = ids.force_adr
        self._s_axes = sensor("ahead:ft_x")
        self._s_ft_pos = sensor("ahead:ft_pos")
        self._s_com = sensor("ahead:tool_com")
        self._s_tcp = sensor("ahead:tcp")
        self._s_parts = {p: sensor(f"ahead:part:{p}") for p in ids.part_bodies}
        self._qpos0 = 1  # time, then qpos, in a FULLPHYSICS state
        self._qvel0 = 1 + m.nq
        self.usable = (
            self._s_arm >= 0
            and self._s_axes >= 0
            and all(a >= 0 for a in self._s_parts.values())
            and (world.changer is None or self._s_tcp >= 0)
        )

    # -- preview --------------------------------------------------------------------------
    def preview_hold(self, periods: int) -> Preview | None:
        """:meth:`preview` of ``periods`` periods with the set-point held where it is
        (the arm still, as when no set-point is sent: no speed feed-forward)."""
        w = self.world
        if not w.holding:
            return None
        q = np.broadcast_to(w.q_ref, (periods, 6))
        ctrl = q if w.substeps == 1 else None  # what step_period feeds the servos then
        return self.preview(q, np.zeros((periods, 6)), ends=(w.q_ref, w.qd_ref), ctrl=ctrl)

    def preview(
        self,
        q_rad: np.ndarray,
        qd_rad_s: np.ndarray,
        ends: tuple[np.ndarray, np.ndarray] | None = None,
        ctrl: np.ndarray | None = None,
    ) -> Preview | None:
        """Roll the physics out over one period per row of ``q_rad``/``qd_rad_s`` (the
        set-points of the coming periods, the first being the one now commanded); None
        when the twin is in no state to be looked ahead. ``ends``: the set-point the twin
        keeps afterwards (a hold); ``ctrl``: the servos' inputs per physics step, where
        they are not :meth:`SimWorld.servo_inputs`."""
        w = self.world
        mode = self._mode()
        if mode is None or not len(q_rad) or not self._calm(mode, w.data.sensordata[None])[0]:
            return None  # not now, or the period just stepped was no plain motion already
        mj, m, d = self._mj, w.model, w.data
        w.drive_outputs()  # what the first period does first; a no-op for the others
        k = w.substeps
        n = len(q_rad)
        state0 = np.empty((1, self._nstate))
        mj.mj_getState(m, d, state0[0], self._full)
        warm0 = d.qacc_warmstart.copy().reshape(1, -1)
        user = np.empty(self._nuser)
        mj.mj_getState(m, d, user, self._user)
        control = np.empty((1, n * k, self._nuser))
        control[0] = user
        control[0, :, 0:6] = w.servo_inputs(q_rad, qd_rad_s) if ctrl is None else ctrl
        states = np.empty((1, n * k, self._nstate))
        sensordata = np.empty((1, n * k, m.nsensordata))
        scratch = self._scratch
        self._rollout.rollout(
            [m],
            [scratch],
            n * k,
            self._user,
            state0,
            warm0,
            control,
            states,
            sensordata,
            None,
        )
        if any(scratch.warning[i].number for i in range(len(scratch.warning))):
            return None  # the rollout stopped early at a warning: step period by period
        last = slice(k - 1, None, k)  # what each period's judgements read: its last step
        sd, st = sensordata[0, last], states[0, last]
        quiet = self._quiet_periods(mode, sd, st, w.periods)
        periods = w.periods + np.arange(1, n + 1)
        return Preview(
            quiet=quiet,
            time_s=periods / w.description.rate_hz,
            q_rad=st[:, self._qpos0 : self._qpos0 + 6],
            _ahead=self,
            _sensordata=sd,
            _state0=state0,
            _warm0=warm0,
            _control=control,
            _q_ref=q_rad,
            _qd_ref=qd_rad_s,
            _ends=ends,
        )

    def _mode(self) -> str | None:
        """'free' (nothing held, nothing may touch the arm), 'carry' (one part between
        both pads, touching nothing else) or None (do not look ahead)."""
        w = self.world
        if (
            not self.usable
            or w.safety is not Safety.NORMAL
            or w.stopping
            or not w.powered
            or (w.vacuum is not None and not w.vacuum.idle)
            or (w.changer is not None and not w.changer.steady)
            or w.grip_faults.active
            or w.grip_faults.grip_miss_armed
            or (w.press_fits is not None and (w.press_fits.engaged() or w.gripped))
        ):
            return None
        jaws = w.jaws
        closing = jaws is not None and jaws.closing
        gripped = w.gripped
        if not gripped:
            return "free" if closing or not w.contacts.held_at else None
        if len(gripped) != 1 or not closing or self._s_part < 0 or self._s_pad[0] < 0:
            return None
        if w.jaw_welds is not None and w.jaw_welds.pending(gripped):
            return None  # the part is welded in a coming period: period by period until then
        (part,) = gripped
        g = w.ids.part_geom[part]
        m = w.model
        for name in ("ahead:pad_a", "ahead:pad_b"):
            m.sensor_refid[self._sensor_id[name]] = g
        m.sensor_objid[self._sensor_id["ahead:part"]] = g
        return "carry"

    def _quiet_periods(self, mode: str, sd: np.ndarray, st: np.ndarray, periods0: int) -> int:
        """How many leading periods pass with no contact verdict and no input change."""
        calm = self._calm(mode, sd) & self._inputs_unchanged(sd, st, periods0)
        changer = self.world.changer
        if changer is not None:
            calm &= ~changer.parks_at(sd[:, self._s_tcp : self._s_tcp + 3])
        bad = np.flatnonzero(~calm)
        return int(bad[0]) if len(bad) else len(calm)

    def _calm(self, mode: str, sd: np.ndarray) -> np.ndarray:
        """Per row of sensor readings: the contacts a plain motion has in ``mode``
        ('free': none on the arm, tool or pads; 'carry': the part on both pads, and
        nothing else on the part or the arm)."""
        arm = sd[:, self._s_arm]
        if mode == "free":
            return np.asarray(arm == 0)
        a, b = sd[:, self._s_pad[0]], sd[:, self._s_pad[1]]
        on_pads = a + b
        return np.asarray((a >= 1) & (b >= 1) & (arm == on_pads) & (sd[:, self._s_part] == on_pads))

    def _inputs_unchanged(self, sd: np.ndarray, st: np.ndarray, periods0: int) -> np.ndarray:
        """Per period: every input the twin drives reads what it reads now."""
        w = self.world
        n = len(sd)
        same = np.ones(n, dtype=bool)
        inputs = w.inputs
        jaws = w.jaws
        if jaws is not None:
            g = jaws.gripper
            a, b = jaws.qpos_adr
            va, vb = jaws.dof_adr
            q0, v0 = self._qpos0, self._qvel0
            gap = g.stroke_m - (st[:, q0 + a] + st[:, q0 + b])
            resting = np.maximum(np.abs(st[:, v0 + va]), np.abs(st[:, v0 + vb])) < (
                JAW_REST_SPEED_MPS
            )
            was = bool(inputs[g.closed_sensor_input]) if g.closed_sensor_input else False
            closed, opened = switch_readings(g, gap, resting, jaws.closing, was)
            if g.closed_sensor_input:
                same &= closed == was
            if g.open_sensor_input:
                same &= opened == bool(inputs[g.open_sensor_input])
        sensors = w.description.presence_sensors
        rules = w.input_rules
        if not sensors and rules is None:
            return same
        positions = {p: sd[:, adr : adr + 3] for p, adr in self._s_parts.items()}
        for sensor in sensors:
            inside = np.zeros(n, dtype=bool)
            for xyz in positions.values():
                inside |= sensor.sees(xyz)
            same &= inside == bool(inputs[sensor.channel])
        if rules is not None:
            rate = w.description.rate_hz
            for i in range(n):  # rules are Python; evaluated without touching their state
                if not same[i]:
                    break
                values = rules.peek(
                    (periods0 + i + 1) / rate,
                    w.outputs,
                    (xyz[i].tolist() for xyz in positions.values()),
                )
                if values is None or any(inputs[c] != v for c, v in values.items()):
                    same[i:] = False
                    break
        return same

    def _wrench(self, sd: np.ndarray) -> np.ndarray:
        """The wrist wrench each period (N, N m, base axes, less the zeroing offset),
        computed as :meth:`WristSensor.raw_wrench_base` computes it, element by element."""
        w = self.world
        f = self._s_ft
        fx, fy, fz, tx, ty, tz = (sd[:, f + i] for i in range(6))
        s = self._s_axes  # x axis column, y axis column, z axis column of the site frame
        r00, r10, r20 = sd[:, s], sd[:, s + 1], sd[:, s + 2]
        r01, r11, r21 = sd[:, s + 3], sd[:, s + 4], sd[:, s + 5]
        r02, r12, r22 = sd[:, s + 6], sd[:, s + 7], sd[:, s + 8]
        cx, cy = sd[:, self._s_com], sd[:, self._s_com + 1]
        sx, sy = sd[:, self._s_ft_pos], sd[:, self._s_ft_pos + 1]
        return w.wrist.wrench_from(
            (fx, fy, fz, tx, ty, tz), (r00, r01, r02, r10, r11, r12, r20, r21, r22), cx, cy, sx, sy
        )

    # -- commit ---------------------------------------------------------------------------
    def commit(self, preview: Preview, periods: int) -> None:
        """Let the twin take over the first ``periods`` periods of ``preview`` (at most
        its quiet ones): afterwards it stands exactly where ``periods`` calls of
        :meth:`SimWorld.step_period` with those set-points would have left it."""
        if not 0 < periods <= preview.quiet:
            raise ValueError(f"cannot take over {periods} of {preview.quiet} quiet periods")
        w, mj = self.world, self._mj
        k = w.substeps
        if periods == preview.periods:
            mj.mj_copyData(w.data, w.model, self._scratch)
        else:  # the same steps again, on the twin's own data, as far as asked
            self._rollout.rollout(
                [w.model],
                [w.data],
                periods * k,
                self._user,
                preview._state0,
                preview._warm0,
                np.ascontiguousarray(preview._control[:, : periods * k]),
                None,
                None,
                None,
            )
        last = periods - 1
        if preview._ends is not None:
            w.advanced(periods, *preview._ends)
        else:
            w.advanced(periods, preview._q_ref[last], preview._qd_ref[last])


def _rollout_module() -> Any:
    """MuJoCo's rollout engine, run on the calling thread (no pool)."""
    from mujoco import _rollout

    return _rollout.Rollout(nthread=0)
