"""Lazy, configured import of MuJoCo; the only place this package imports it.

MuJoCo picks its OpenGL backend from ``MUJOCO_GL`` once, when it is first imported. On a
machine without a display we default that to ``osmesa`` (software, offscreen) before the
import, so that rendering a report works headless; an explicit ``MUJOCO_GL`` always wins.
"""

from __future__ import annotations

import os
import sys
from types import ModuleType


def load_mujoco() -> ModuleType:
    """Import and return the ``mujoco`` module (choosing a headless GL backend first)."""
    if "mujoco" not in sys.modules and not os.environ.get("MUJOCO_GL"):
        if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            os.environ["MUJOCO_GL"] = "osmesa"
    import mujoco

    return mujoco
