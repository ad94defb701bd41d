"""Files built to hurt the loader: each is refused with one located line
``FILE:LINE:COL: error: ...``, exit 2, within 2 s of CPU and 500 MB of memory.

Every case runs ``cellrunner validate`` as its own process, measured by ``os.wait4`` (the
child's own CPU time and peak memory, not the machine's load)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.conftest import DEMO_CELL

CPU_BUDGET_S = 2.0
MEMORY_BUDGET_KB = 500 * 1024
DEMO = DEMO_CELL.read_text()


def _home_with(value: str) -> str:
    """The demo cell with ``value`` as the sixth home angle."""
    return DEMO.replace("home: [0, -90, 90, -90, -90, 0]", f"home: [0, -90, 90, -90, -90, {value}]")


def _line_col(text: str, needle: str) -> str:
    index = text.index(needle)
    line = text.count("\n", 0, index) + 1
    return f"{line}:{index - (text.rfind(chr(10), 0, index) + 1) + 1}"


def _alias_bomb() -> str:
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    lines += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 10)}]" for i in range(1, 10)]
    return "\n".join(lines) + "\ncell: *a9\n"


# name -> (bytes of the file, expected "LINE:COL", text the message holds)
CASES: dict[str, Callable[[], tuple[bytes, str, str]]] = {
    "huge_int": lambda: (
        _home_with("1" + "0" * 400).encode(),
        _line_col(_home_with("1" + "0" * 400), "1" + "0" * 400),
        "a number of 401 characters",
    ),
    "float_overflow": lambda: (
        _home_with("1e400").encode(),
        _line_col(_home_with("1e400"), "1e400"),
        "1e400 is not a finite number",
    ),
    "deep_lists": lambda: (b"cell: " + b"[" * 100_000 + b"]" * 100_000 + b"\n", "1:70", "nested"),
    "deep_maps": lambda: (b"cell: " + b"{a: " * 20_000 + b"1" + b"}" * 20_000, "1:256", "nested"),
    "alias_bomb": lambda: (_alias_bomb().encode(), "*", "once its aliases are expanded"),
    "alias_in_itself": lambda: (b"cell: &a [1, *a]\n", "1:7", "an alias inside the value"),
    "many_values": lambda: (
        b"cell: [" + b"1," * 200_000 + b"1]\n",
        "1:60002",
        "more than 30000 values in one file",
    ),
    "fifty_megabytes": lambda: (b"cell: '" + b"A" * 50_000_000 + b"'\n", "1:1", "limited to"),
    "not_utf8": lambda: (
        DEMO.replace("model: ur5e", "model: ur5\udcffe").encode("utf-8", "surrogateescape"),
        _line_col(DEMO, "model: ur5e").split(":")[0]
        + ":"
        + str(int(_line_col(DEMO, "model: ur5e").split(":")[1]) + len("model: ur5")),
        "byte ff is not UTF-8",
    ),
}


#: runs ``cellrunner validate`` and writes its own peak resident KB (VmHWM, the peak of
#: this process's memory) to argv[1] at exit. wait4's ru_maxrss is no measure here: Linux
#: carries the parent's peak over fork and exec, so a child of a big test process (an
#: xdist worker at 800 MB) reports at least the parent's size.
_MEASURED = (
    "import atexit, re, sys\n"
    "out = sys.argv.pop(1)\n"
    "def peak():\n"
    "    status = open('/proc/self/status').read()\n"
    "    open(out, 'w').write(re.search(r'VmHWM:\\s*(\\d+)', status).group(1))\n"
    "atexit.register(peak)\n"
    "from cellrunner.cli.main import main\n"
    "sys.exit(main())\n"
)


def _validate(path: Path, cwd: Path) -> tuple[int, str, float, int]:
    """Exit code, stderr, CPU seconds and peak resident KB of ``cellrunner validate``."""
    peak_file = cwd / "peak_kb"
    proc = subprocess.Popen(
        [sys.executable, "-c", _MEASURED, str(peak_file), "validate", str(path)],
        cwd=cwd,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    assert proc.stderr is not None
    err = proc.stderr.read(2_000_000).decode("utf-8", "replace")
    try:
        _, status, usage = os.wait4(proc.pid, 0)
    finally:
        proc.returncode = 0  # reaped above
    cpu_s = usage.ru_utime + usage.ru_stime
    return os.waitstatus_to_exitcode(status), err, cpu_s, int(peak_file.read_text())


@pytest.mark.parametrize("case", sorted(CASES))
def test_hostile_file_is_refused_located_fast_and_small(case, tmp_path):
    data, where, text = CASES[case]()
    path = tmp_path / "cell.yaml"
    path.write_bytes(data)
    code, err, cpu_s, peak_kb = _validate(path, tmp_path)
    assert code == 2, err[-2000:]
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1, err[-2000:]
    prefix = "cell.yaml:" + ("" if where == "*" else f"{where}: error: ")
    assert lines[0].startswith(prefix), lines[0][:300]
    assert re.match(r"^[^:]+:\d+:\d+: error: ", lines[0])
    assert text in lines[0], lines[0][:300]
    assert len(err) < 1200, f"{len(err)} characters of stderr"
    assert cpu_s < CPU_BUDGET_S, f"{cpu_s:.2f} s of CPU"
    assert peak_kb < MEMORY_BUDGET_KB, f"{peak_kb / 1024:.0f} MB"


def test_a_long_bad_value_is_echoed_by_its_start_and_length(tmp_path):
    value = "u" * 400_000
    path = tmp_path / "cell.yaml"
    path.write_text(DEMO.replace("model: ur5e", f'model: "{value}"'))
    code, err, _, _ = _validate(path, tmp_path)
    assert code == 2
    line = err.strip()
    assert "unknown robot model 'uuuuuuuuuu" in line
    assert "...' (400000 characters); known: ur3, ur5" in line
    assert len(line) < 400


def test_a_symlink_loop_is_named_where_it_is_written(tmp_path):
    (tmp_path / "a.yaml").symlink_to("b.yaml")
    (tmp_path / "b.yaml").symlink_to("a.yaml")
    code, err, _, _ = _validate(Path("a.yaml"), tmp_path)
    assert code == 2
    assert err == "a.yaml:1:1: error: cannot read a.yaml: a loop of symbolic links\n"
    (tmp_path / "tasks").mkdir()
    (tmp_path / "tasks" / "l1.yaml").symlink_to("l2.yaml")
    (tmp_path / "tasks" / "l2.yaml").symlink_to("l1.yaml")
    cell = DEMO.replace("tasks: {1: tasks/pick_place.yaml", "tasks: {1: tasks/l1.yaml")
    (tmp_path / "cell.yaml").write_text(cell)
    code, err, _, _ = _validate(Path("cell.yaml"), tmp_path)
    assert code == 2
    where = _line_col(cell, "tasks/l1.yaml")
    assert err.startswith(
        f"cell.yaml:{where}: error: tasks[1]: task file 'tasks/l1.yaml' is a loop of symbolic links"
    ), err
