"""Lazy, configured import of MuJoCo; the only place this package imports it, and the one
place that decides whether this process draws with OpenGL.

MuJoCo picks its OpenGL backend from ``MUJOCO_GL`` once, when it is first imported, and
loading a backend whose library is missing (``osmesa`` without libOSMesa) breaks the
import itself. So GL is used only where pictures or depth images are asked for:

- a run that draws nothing (``check``, a plain ``dry-run``, ``twin`` without cameras)
  imports MuJoCo with GL off, whatever ``MUJOCO_GL`` says, and needs no GL library;
- a run that draws calls :func:`enable_pictures` before anything imports MuJoCo. It keeps
  an explicit ``MUJOCO_GL`` when that backend's library loads here, else tries EGL,
  then OSMesa (then GLFW where there is a display), each in a child process. When none
  works, GL stays off and :func:`no_gl_reason` says why in one line, with the package
  that gives pictures (:data:`GL_ADVICE`).
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


class _Choice:
    """What this process decided: the backend to draw with (None: GL off), decided yet,
    and why there is none."""

    backend: str | None = None
    decided = False
    reason = "no OpenGL backend here"


def load_mujoco() -> ModuleType:
    """Import and return ``mujoco``, with GL off unless :func:`enable_pictures` found a
    backend first."""
    if "mujoco" not in sys.modules:
        if not _Choice.decided:
            _Choice.reason = "pictures were not asked for before MuJoCo was imported"
        _import_with(_Choice.backend if _Choice.decided else None)
    import mujoco

    module: ModuleType = mujoco  # untyped bindings
    return module


def _import_with(backend: str | None) -> None:
    """Import MuJoCo drawing with ``backend`` (None: GL off). ``MUJOCO_GL`` is set for
    the import and put back after it, so child processes still see what the user chose."""
    saved = {k: os.environ.get(k) for k in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    os.environ["MUJOCO_GL"] = backend or "disable"
    if backend in GL_BACKENDS:
        # PyOpenGL must load the same platform; an inherited PYOPENGL_PLATFORM (a parent
        # that rendered with another backend) would break the context
        os.environ["PYOPENGL_PLATFORM"] = backend
    try:
        import mujoco  # noqa: F401
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value
    _Choice.backend, _Choice.decided = backend, True


def gl_backend() -> str | None:
    """The GL backend MuJoCo draws with in this process; None when GL is off."""
    if _Choice.decided:
        return _Choice.backend
    if "mujoco" in sys.modules:  # imported by someone else: it read MUJOCO_GL itself
        return _requested()
    return None


def no_gl_reason() -> str:
    """Why this process draws no pictures, in a few words (see :data:`GL_ADVICE`)."""
    return _Choice.reason


def _requested() -> str | None:
    chosen = os.environ.get("MUJOCO_GL", "").lower().strip()
    if chosen in _OFF:
        return None
    return chosen or None


def enable_pictures() -> str | None:
    """Choose an offscreen GL backend before MuJoCo is imported; returns it, or None.

    An explicit ``MUJOCO_GL`` is kept when its library loads here; otherwise each of
    :data:`GL_BACKENDS` (and ``glfw`` when a display is set) is tried in a child process,
    which imports MuJoCo and makes a context; the first that works is used. Once MuJoCo
    is imported the choice is final, and this returns what was chosen then.
    """
    if _Choice.decided or "mujoco" in sys.modules:
        return gl_backend()
    requested = _requested()
    if requested is not None:
        candidates = [requested]
    elif os.environ.get("MUJOCO_GL", "").lower().strip() in _OFF and os.environ.get("MUJOCO_GL"):
        candidates = []  # GL switched off on purpose
    else:
        candidates = list(GL_BACKENDS)
        if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
            candidates.append("glfw")
    for backend in candidates:
        works = _library_loads(backend) if backend == requested else _context_works(backend)
        if works:
            _Choice.backend, _Choice.decided = backend, True
            return backend
    _Choice.backend, _Choice.decided = None, True
    if requested is not None:
        _Choice.reason = f"MUJOCO_GL={requested} cannot draw here"
    elif not candidates:
        _Choice.reason = "MUJOCO_GL switches OpenGL off"
    return None


#: the library each offscreen backend loads (ctypes.util names, then a file name)
_LIBRARIES = {"osmesa": ("OSMesa", "libOSMesa.so.8"), "egl": ("EGL", "libEGL.so.1")}


def _library_loads(backend: str) -> bool:
    """Whether the library of an explicitly chosen ``backend`` loads here (cheap, in this
    process: a missing one would break MuJoCo's import). A backend that loads but cannot
    make a context still imports; drawing then says why."""
    import ctypes
    import ctypes.util

    names = _LIBRARIES.get(backend)
    if names is None:
        return True  # glfw or another: MuJoCo's own business
    short, file = names
    for candidate in (ctypes.util.find_library(short), file):
        if candidate:
            try:
                ctypes.CDLL(candidate)
                return True
            except OSError:
                continue
    return False


def _context_works(backend: str) -> bool:
    """Can MuJoCo make a GL context with ``backend`` here? (tried in a child process)"""
    env = {**os.environ, "MUJOCO_GL": backend}
    if backend in GL_BACKENDS:
        env["PYOPENGL_PLATFORM"] = backend
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
