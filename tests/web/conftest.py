"""Fixtures the status page's tests share."""

from tests.web.live_rig import live_serving  # noqa: F401  (a fixture: serve with the live view)
