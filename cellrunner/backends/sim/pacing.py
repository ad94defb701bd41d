"""The sim backend's look-aheads (:mod:`cellrunner.sim.lookahead`): many periods of a
streamed motion or a hold per call, paced so that a look-ahead cut short (a contact, an
input, a check ahead) does not waste the physics beyond its cut. Part of
:class:`.backend.SimBackend` (its look-ahead methods delegate here)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from cellrunner.model.trajectory import ApprovedTrajectory
    from cellrunner.sim.lookahead import Lookahead, Preview
    from cellrunner.sim.world import SimWorld

#: a look-ahead covers this many periods at first, doubling while they pass whole up
#: to the most; one cut short (a contact, an input, a check ahead) starts again small,
#: since its physics beyond the cut is computed in vain
AHEAD_FIRST_PERIODS = 64
AHEAD_MAX_PERIODS = 1024
#: a hold's look-ahead starts this small when an output changed since the last
#: look-ahead (the jaws moving soon cut it: a contact, the sensor), else at most this
#: big (a hold's end in time bounds it too)
AHEAD_FIRST_HOLD_PERIODS = 16
AHEAD_CALM_HOLD_PERIODS = 256


class LookaheadPacer:
    """The look-aheads of one SimBackend (its world, connection and accepted trajectory)."""

    def __init__(self, backend: Any) -> None:
        self.backend = backend
        self.ahead: Lookahead | None = None
        self._ahead_cap = AHEAD_FIRST_PERIODS  # grows while look-aheads pass whole
        self._ahead_not_before = 0  # no look-ahead before this period (a cut one's end)
        # a hold's cap, apart: it starts small again when an output changed (the jaws
        # moving soon end a hold's quiet stretch, and the periods rolled out beyond such a
        # cut are wasted)
        self._hold_cap = AHEAD_FIRST_HOLD_PERIODS
        self._ahead_outputs: dict[str, bool | float] | None = None  # at the last look-ahead

    def look_ahead(
        self, trajectory: ApprovedTrajectory, next_index: int, periods: int
    ) -> Preview | None:
        """The coming periods' measurements if ``trajectory`` keeps streaming (set-point
        ``next_index - 1``, the one commanded last, then one more each period), without
        taking them yet; None when the twin cannot look ahead now. Covers at most
        ``periods`` periods (fewer after a look-ahead that was cut short)."""
        b = self.backend
        world = b.world
        accepted = b._accepted
        if (
            world is None
            or not b._connected
            or accepted is None
            or accepted[0] is not trajectory
            or next_index != b._next_index
            or world.q_ref is not b._last_q
            or next_index < 1
            or world.periods < self._ahead_not_before
        ):
            return None
        self._outputs_changed(world)
        self._hold_cap = AHEAD_CALM_HOLD_PERIODS
        n = min(periods, self._ahead_cap, len(accepted[1]) - next_index + 1)
        j0 = next_index - 1
        preview = self.lookahead(world).preview(accepted[1][j0 : j0 + n], accepted[2][j0 : j0 + n])
        if self._cut_short(world, preview, n):
            self._ahead_cap = AHEAD_FIRST_PERIODS
        return preview

    def look_ahead_hold(self, periods: int) -> Preview | None:
        """The coming periods' measurements if the set-point stays where it is (a step
        waiting with the arm still), without taking them yet; None when the twin cannot
        look ahead now. Covers at most ``periods`` periods."""
        b = self.backend
        world = b.world
        if (
            world is None
            or not b._connected
            or world.periods < self._ahead_not_before
            or world.stopping
        ):
            return None
        if self._outputs_changed(world):
            self._hold_cap = AHEAD_FIRST_HOLD_PERIODS
        n = min(periods, self._hold_cap)
        preview = self.lookahead(world).preview_hold(n)
        if self._cut_short(world, preview, n):
            self._hold_cap = AHEAD_FIRST_HOLD_PERIODS
        return preview

    def lookahead(self, world: SimWorld) -> Lookahead:
        """The world's look-ahead engine, made at the first look-ahead."""
        if self.ahead is None:
            from cellrunner.sim.lookahead import Lookahead

            self.ahead = Lookahead(world)
        return self.ahead

    def _outputs_changed(self, world: SimWorld) -> bool:
        """Whether the outputs changed since the last look-ahead (remembered from now)."""
        if world.outputs == self._ahead_outputs:
            return False
        self._ahead_outputs = dict(world.outputs)
        return True

    def _cut_short(self, world: SimWorld, preview: Preview | None, n: int) -> bool:
        """Whether ``preview`` of ``n`` periods ends before them: the period after its
        quiet ones is no plain motion or hold, so no look-ahead starts before it."""
        if preview is None or preview.quiet >= n:
            return False
        self._ahead_not_before = world.periods + preview.quiet + 1
        return True

    def commit_look_ahead(self, preview: Preview, periods: int) -> None:
        """Take over the first ``periods`` periods of ``preview`` (at most its quiet
        ones): the twin then stands where that many ``wait_period`` calls, with
        ``servo`` sending the trajectory's set-points between them (none for a hold),
        would have left it."""
        b = self.backend
        assert self.ahead is not None and b.world is not None  # a preview was made
        b._fresh = None
        self.ahead.commit(preview, periods)
        if preview.holds:
            if periods == preview.periods:
                self._hold_cap = min(2 * self._hold_cap, AHEAD_MAX_PERIODS)
            return
        b._last_q = b.world.q_ref
        b._next_index += periods
        if periods == preview.periods:
            self._ahead_cap = min(2 * self._ahead_cap, AHEAD_MAX_PERIODS)

    def discard_look_ahead(self, preview: Preview) -> None:
        """A preview none of whose periods is taken (the next period runs as usual)."""
        if preview.holds:
            self._hold_cap = AHEAD_FIRST_HOLD_PERIODS
        else:
            self._ahead_cap = AHEAD_FIRST_PERIODS
