"""Fixtures of the agreement tests."""

from __future__ import annotations

import pytest


@pytest.fixture
def twin_only(monkeypatch):
    """check's fit rules off: the job runs in the twin as check approved it before them."""
    from cellrunner.steps import _families, insert

    monkeypatch.setattr(insert.Insert, "check_line", lambda *args: None)
    monkeypatch.setattr(_families.FrameLine, "check_line", lambda *args: None)
