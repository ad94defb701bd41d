"""A hang guard: ur_rtde's constructors wait without a timeout for the first state."""

from __future__ import annotations

import faulthandler

import pytest

TEST_TIMEOUT_S = 120


@pytest.fixture(autouse=True)
def _hang_guard():
    faulthandler.dump_traceback_later(TEST_TIMEOUT_S, exit=True)
    yield
    faulthandler.cancel_dump_traceback_later()
