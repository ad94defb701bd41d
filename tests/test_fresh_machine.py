"""The README's first command on a fresh machine: no OpenGL library may be needed for a
plain dry-run, ``check`` or ``twin``, also where ``MUJOCO_GL`` names a backend whose
library is missing, and a report without one still has its plots and JSON and says in one
line which package gives pictures.

"Fresh machine" is made here by hiding every GL library (OSMesa, EGL, GL) in a private
mount namespace: each file is covered by /dev/null, so loading it fails as if it were
absent, for the child process only.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import pytest

from tests.conftest import ROOT

GL_LIBRARIES = ("libOSMesa", "libEGL", "libGL.", "libGLX", "libOpenGL")


def _gl_library_files() -> list[str]:
    """Every GL library file the dynamic loader knows of (ldconfig's cache)."""
    listing = subprocess.run(["ldconfig", "-p"], capture_output=True, text=True, check=True).stdout
    files = {
        line.rsplit("=>", 1)[1].strip()
        for line in listing.splitlines()
        if "=>" in line and any(name in line.split("=>")[0] for name in GL_LIBRARIES)
    }
    return sorted(f for f in files if os.path.exists(f))


def _hidden(argv: list[str], mujoco_gl: str | None) -> tuple[list[str], dict[str, str]]:
    """``argv`` wrapped to run with every GL library unloadable, and its environment (no
    MUJOCO_GL, or ``mujoco_gl``)."""
    assert shutil.which("unshare"), "util-linux's unshare is needed to hide the GL libraries"
    hide = " && ".join(f"mount --bind /dev/null '{f}'" for f in _gl_library_files()) or "true"
    userns = [] if os.geteuid() == 0 else ["-r"]
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    if mujoco_gl is not None:
        env["MUJOCO_GL"] = mujoco_gl
    return ["unshare", *userns, "-m", "sh", "-c", f'{hide} && exec "$@"', "sh", *argv], env


def _without_gl(
    argv: list[str], mujoco_gl: str | None = None, **kwargs
) -> subprocess.CompletedProcess:
    """Run ``argv`` with every GL library unloadable (``mujoco_gl``: MUJOCO_GL set so)."""
    wrapped, env = _hidden(argv, mujoco_gl)
    return subprocess.run(wrapped, capture_output=True, text=True, env=env, cwd=ROOT, **kwargs)


def test_gl_libraries_are_really_hidden():
    probe = (
        "import ctypes, ctypes.util, sys\nfor n in ('OSMesa', 'EGL'):\n"
        "    try:\n        ctypes.CDLL(f'lib{n}.so.' + ('8' if n == 'OSMesa' else '1'))\n"
        "        print(n, 'loaded')\n    except OSError:\n        print(n, 'unloadable')\n"
    )
    r = _without_gl([sys.executable, "-c", probe], timeout=60)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["OSMesa", "unloadable", "EGL", "unloadable"], r.stdout


def test_readme_first_command_needs_no_gl_even_where_mujoco_gl_names_a_missing_one():
    # a plain dry-run draws nothing: MuJoCo is imported with GL off whatever MUJOCO_GL
    # says, so this covers the fresh machine with no MUJOCO_GL at all too
    r = _without_gl(
        [sys.executable, "-m", "cellrunner.cli.main", "dry-run"], mujoco_gl="osmesa", timeout=600
    )
    assert r.returncode == 0, r.stderr[-3000:]
    assert "result 0 OK" in r.stderr
    assert "Traceback" not in r.stderr and "warning" not in r.stderr, r.stderr


@pytest.mark.parametrize(
    ("mujoco_gl", "why"),
    [(None, "no OpenGL backend here"), ("osmesa", "MUJOCO_GL=osmesa cannot draw here")],
)
def test_report_without_gl_keeps_plots_and_json_and_says_what_to_install(tmp_path, mujoco_gl, why):
    report = tmp_path / "report"
    r = _without_gl(
        [sys.executable, "-m", "cellrunner.cli.main", "dry-run", "--report", str(report)],
        mujoco_gl=mujoco_gl,
        timeout=600,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    assert json.loads((report / "result.json").read_text())["result_code"] == 0
    assert (report / "joints.png").stat().st_size > 0 and (
        report / "tcp_path.png"
    ).stat().st_size > 0
    from cellrunner.report.write import PLOT_FILES

    assert not [
        p.name for p in report.glob("*.png") if p.name not in PLOT_FILES
    ]  # plots only, no renders
    assert (report / "index.html").is_file() and (report / "NO_PICTURES.txt").is_file()
    advice = [line for line in r.stderr.splitlines() if "apt-get install libosmesa6" in line]
    assert advice == [f"no pictures in the report: {why} (apt-get install libosmesa6 gives one)"]


def test_check_needs_no_gl_where_mujoco_gl_names_a_missing_one():
    r = _without_gl(
        [sys.executable, "-m", "cellrunner.cli.main", "check", "--no-cache"],
        mujoco_gl="osmesa",
        timeout=600,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    assert "Traceback" not in r.stderr and "error" not in r.stderr, r.stderr


def test_twin_starts_without_gl_where_mujoco_gl_names_a_missing_one():
    wrapped, env = _hidden(
        [
            sys.executable,
            "-m",
            "cellrunner.cli.main",
            "twin",
            str(ROOT / "cells" / "demo_ur5e.yaml"),
            "--host",
            "127.0.0.61",
        ],
        "osmesa",
    )
    proc = subprocess.Popen(
        wrapped, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True
    )
    assert proc.stderr is not None
    try:
        line = proc.stderr.readline()  # the announcement, or the start of a traceback
        assert line.startswith("virtual UR5E controller"), line + proc.stderr.read()
    finally:
        proc.terminate()
        proc.wait(timeout=30)
    assert proc.returncode == 0
