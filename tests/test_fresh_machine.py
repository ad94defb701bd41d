"""The README's first command on a fresh machine: no OpenGL library may be needed for a
plain dry-run, and a report without one still has its plots and JSON.

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


def _without_gl(argv: list[str], **kwargs) -> subprocess.CompletedProcess:
    """Run ``argv`` with every GL library unloadable (and no MUJOCO_GL set)."""
    assert shutil.which("unshare"), "util-linux's unshare is needed to hide the GL libraries"
    hide = " && ".join(f"mount --bind /dev/null '{f}'" for f in _gl_library_files()) or "true"
    userns = [] if os.geteuid() == 0 else ["-r"]
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    return subprocess.run(
        ["unshare", *userns, "-m", "sh", "-c", f'{hide} && exec "$@"', "sh", *argv],
        capture_output=True,
        text=True,
        env=env,
        cwd=ROOT,
        **kwargs,
    )


def test_gl_libraries_are_really_hidden():
    probe = (
        "import ctypes, ctypes.util, sys\nfor n in ('OSMesa', 'EGL'):\n"
        "    try:\n        ctypes.CDLL(f'lib{n}.so.' + ('8' if n == 'OSMesa' else '1'))\n"
        "        print(n, 'loaded')\n    except OSError:\n        print(n, 'unloadable')\n"
    )
    r = _without_gl([sys.executable, "-c", probe], timeout=60)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["OSMesa", "unloadable", "EGL", "unloadable"], r.stdout


def test_readme_first_command_needs_no_gl():
    r = _without_gl([sys.executable, "-m", "cellrunner.cli.main", "dry-run"], timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "result 0 OK" in r.stderr
    assert "Traceback" not in r.stderr and "warning" not in r.stderr, r.stderr


def test_report_without_gl_keeps_plots_and_json_and_says_what_to_install(tmp_path):
    report = tmp_path / "report"
    r = _without_gl(
        [sys.executable, "-m", "cellrunner.cli.main", "dry-run", "--report", str(report)],
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
    assert advice == [
        "no pictures in the report: no OpenGL backend here (apt-get install libosmesa6 gives one)"
    ]
