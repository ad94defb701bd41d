"""Time scaling keeps the approved path; the step gate opens on Enter only."""

from __future__ import annotations

import io

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cellrunner.errors import InternalError
from cellrunner.execution.pacing import EnterGate
from cellrunner.model.trajectory import Trajectory, approve, time_scaled


def _approved(n: int, seed: int = 0):
    q = np.cumsum(np.random.default_rng(seed).normal(size=(n, 6)) * 1e-3, axis=0)
    return approve(Trajectory(500.0, np.arange(n) / 500.0, q), 3, "x")


@settings(max_examples=40, deadline=None)
@given(n=st.integers(2, 300), speed=st.floats(0.05, 1.0), seed=st.integers(0, 1000))
def test_scaled_trajectory_stays_on_the_approved_segments(n, speed, seed):
    approved = _approved(n, seed)
    scaled = time_scaled(approved, speed)
    q, q0 = scaled.trajectory.q_rad, approved.trajectory.q_rad
    assert scaled.is_sealed and scaled.trajectory.rate_hz == 500.0
    assert np.array_equal(q[0], q0[0]) and np.array_equal(q[-1], q0[-1])
    assert len(q) - 1 == pytest.approx((n - 1) / speed, abs=1.0)
    u = np.minimum(np.arange(len(q)) * speed, n - 1)  # where each set-point is on the source
    expected = np.column_stack([np.interp(u, np.arange(n), q0[:, j]) for j in range(6)])
    assert np.allclose(q, expected, atol=1e-12)
    speeds = np.abs(np.diff(q, axis=0)).max()
    assert speeds <= np.abs(np.diff(q0, axis=0)).max() * speed * (1 + 1e-9) + 1e-15


def test_only_sealed_trajectories_at_a_fraction_of_their_pace():
    approved = _approved(10)
    with pytest.raises(InternalError, match="outside"):
        time_scaled(approved, 1.5)
    forged = type(approved)(approved.trajectory, 3, "x", "0" * 64)
    with pytest.raises(InternalError, match="only an approved"):
        time_scaled(forged, 0.5)


class _Step:
    index, label = 2, "step 2 wait"


def test_the_gate_opens_on_an_enter_typed_after_the_question():
    lines = io.StringIO("\n")
    out = io.StringIO()
    gate = EnterGate(lambda s: s.label, source=lines, out=out)
    gate._read()  # the reader thread's work, here in line: one Enter, then end of input
    assert gate(_Step()) is False, "typed before the question: does not count"
    assert "next: step 2 wait" in out.getvalue()
    gate._lines.release()  # an Enter after the question
    assert gate(_Step()) is True
