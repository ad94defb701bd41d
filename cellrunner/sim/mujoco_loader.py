"""Lazy, configured import of MuJoCo; the only place this package imports it.

MuJoCo picks its OpenGL backend from ``MUJOCO_GL`` once, when it is first imported, and
loading a backend whose library is missing (``osmesa`` without libOSMesa) breaks the
import itself. So a run that draws nothing imports MuJoCo with GL off
(``MUJOCO_GL=disable``) and needs no GL library at all; a run that wants pictures calls
:func:`enable_pictures` before anything imports MuJoCo, which picks the first offscreen
backend that can really make a context here: EGL, then OSMesa (then GLFW where there is a
display). An explicit ``MUJOCO_GL`` always wins.
"""

from __future__ import annotations

import os
import subprocess
import sys
from types import ModuleType

#: offscreen GL backends, in the order :func:`enable_pictures` tries them
GL_BACKENDS = ("egl", "osmesa")
#: what to install where no backend works (Debian's package; software rendering)
GL_ADVICE = "apt-get install libosmesa6"
_OFF = ("disable", "disabled", "off", "false", "0")
_PROBE_TIMEOUT_S = 60.0
_PROBE = "import mujoco\nc = mujoco.GLContext(16, 16)\nc.make_current()\nc.free()\nprint('gl-ok')\n"


def load_mujoco() -> ModuleType:
    """Import and return ``mujoco``; GL stays off unless pictures were asked for first."""
    if "mujoco" not in sys.modules:
        if not os.environ.get("MUJOCO_GL"):
            os.environ["MUJOCO_GL"] = "disable"
        backend = gl_backend()
        if backend in GL_BACKENDS:
            # PyOpenGL must load the same platform; an inherited PYOPENGL_PLATFORM (a parent
            # that rendered with another backend) would break the context
            os.environ["PYOPENGL_PLATFORM"] = backend
    import mujoco

    module: ModuleType = mujoco  # untyped bindings
    return module


def gl_backend() -> str | None:
    """The GL backend MuJoCo uses (or will use) in this process; None when GL is off."""
    chosen = os.environ.get("MUJOCO_GL", "").lower().strip()
    if chosen in _OFF:
        return None
    return chosen or "glfw"


def enable_pictures() -> str | None:
    """Choose an offscreen GL backend before MuJoCo is imported; returns it, or None.

    Keeps an explicit ``MUJOCO_GL``. Otherwise each of :data:`GL_BACKENDS` (and ``glfw``
    when a display is set) is tried in a child process, which imports MuJoCo and makes a
    context; the first that works is set for this process. Once MuJoCo is imported the
    choice is final, and this returns what was chosen then.
    """
    if "mujoco" in sys.modules or os.environ.get("MUJOCO_GL"):
        return gl_backend()
    candidates = list(GL_BACKENDS)
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        candidates.append("glfw")
    for backend in candidates:
        if _context_works(backend):
            os.environ["MUJOCO_GL"] = backend
            return backend
    os.environ["MUJOCO_GL"] = "disable"
    return None


def _context_works(backend: str) -> bool:
    """Can MuJoCo make a GL context with ``backend`` here? (tried in a child process)"""
    env = {**os.environ, "MUJOCO_GL": backend}
    try:
        done = subprocess.run(
            [sys.executable, "-c", _PROBE],
            env=env,
            capture_output=True,
            text=True,
            timeout=_PROBE_TIMEOUT_S,
            check=False,
        )
    except (OSError, subprocess.TimeoutExpired):
        return False
    return done.returncode == 0 and "gl-ok" in done.stdout
