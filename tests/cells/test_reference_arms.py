"""Reference cells for arms beyond the demo's (issue 9, SPEC section 11), as CI runs them:
`check` proves every slot of the pattern, then `dry-run` rehearses chosen slots on the
twin and the part must end where the task put it. Also the README's and the SPEC's
example cells, which must pass `check` as written."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from tests.cells.meshes import box_triangles, write_stl
from tests.conftest import ROOT
from tests.rig import cli

#: (cell, task, param, slot count, {slot: where the part must end, world m})
CELLS = {
    "ur5": (
        "cells/bin_to_shelf_ur5.yaml",
        "tasks/bin_to_shelf_ur5.yaml",
        "slot",
        6,
        {0: (0.59, -0.22, 0.86), 5: (0.59, 0.22, 1.11)},
    ),
    "ur20": (
        "cells/case_palletizer_ur20.yaml",
        "tasks/palletize_cases.yaml",
        "slot",
        18,
        {0: (0.705, -0.045, 0.254), 5: (1.015, 0.775, 0.254)},  # bottom layer (one case)
    ),
    "ur10e": (
        "cells/bin_to_shelf_ur10e.yaml",
        "tasks/bin_to_shelf_ur10e.yaml",
        "slot",
        9,
        {0: (0.82, -0.26, 0.65), 5: (0.82, 0.0, 1.25)},
    ),
    "ur3e": (
        "cells/kitting_ur3e.yaml",
        "tasks/kitting.yaml",
        "pocket",
        8,
        {0: (0.275, 0.225, 0.885), 7: (0.325, 0.075, 0.885)},
    ),
}


@pytest.mark.parametrize("arm", sorted(CELLS))
def test_check_proves_every_slot(arm):
    cell, task, param, count, _ = CELLS[arm]
    r = cli("check", cell, task, "--json")
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-2000:]
    out = json.loads(r.stdout)
    assert out["ok"] and out["errors"] == [] and out["failed_slots"] == []
    assert out["slots_checked"] == {param: list(range(count))}
    assert out["cycle_time_s"] > 0


@pytest.mark.parametrize(
    ("arm", "slot"), [(arm, slot) for arm in sorted(CELLS) for slot in CELLS[arm][4]]
)
def test_dry_run_puts_the_part_in_its_slot(arm, slot):
    cell, task, param, _, ends = CELLS[arm]
    r = cli("dry-run", cell, task, "-p", f"{param}={slot}", "--json")
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-2000:]
    out = json.loads(r.stdout)
    assert (out["result_code"], out["result_text"]) == (0, "OK")
    # the earlier slots' parts are in place (PART@slot=K, where the task put them); the
    # job's own part is the one without a slot in its name
    (end,) = (xyz for name, xyz in out["parts_end_m"].items() if "@" not in name)
    assert np.allclose(end, ends[slot], atol=0.005), end
    earlier = {name for name in out["parts_end_m"] if "@" in name}
    assert earlier == {
        f"{name}@{param}={k}" for name in out["parts_end_m"] if "@" not in name for k in range(slot)
    }


def _yaml_blocks(text: str) -> list[str]:
    return re.findall(r"```yaml\n(.*?)```", text, re.S)


def _check_example(root: Path, cell_yaml: str, task_yaml: str) -> dict:
    (root / "cells").mkdir()
    (root / "tasks").mkdir()
    (root / "cells" / "cell.yaml").write_text(cell_yaml)
    (root / "tasks" / "pick_place.yaml").write_text(task_yaml)
    (root / "tasks" / "home.yaml").write_text((ROOT / "tasks" / "home.yaml").read_text())
    r = cli("check", "cells/cell.yaml", "tasks/pick_place.yaml", "--json", cwd=root)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-2000:]
    out = json.loads(r.stdout)
    assert out["ok"] and out["slots_checked"] == {"slot": list(range(12))}
    return out


def test_readme_example_passes_check(tmp_path):
    cell, task = _yaml_blocks((ROOT / "README.md").read_text())[:2]
    # the README shows the repository's demo files as they are, and they pass check
    assert cell == (ROOT / "cells" / "demo_ur5e.yaml").read_text()
    assert task == (ROOT / "tasks" / "pick_place.yaml").read_text()
    _check_example(tmp_path, cell, task)


SPEC_EXAMPLE = ROOT / "tests" / "data" / "spec_example"
SPEC = ROOT.parent / "shared" / "SPEC.md"


def test_spec_example_is_checked_and_its_slots_off_the_table_refused(tmp_path):
    """SPEC section 3 and 4's example files (kept in tests/data/spec_example, checked
    against the SPEC wherever it sits beside the project), with a fence mesh made here.
    The example's pallet pattern runs past the table's edge (y 0.30 + 3 x 0.07 > 0.40):
    slots 8-11 would let the block go over the floor, and the twin drops it there (3).
    check plans every slot and refuses exactly those four, saying why."""
    cell = (SPEC_EXAMPLE / "cell.yaml").read_text()
    task = (SPEC_EXAMPLE / "pick_place.yaml").read_text()
    if SPEC.is_file():  # the copy is the SPEC's own text
        assert _yaml_blocks(SPEC.read_text())[:2] == [cell, task]
    (tmp_path / "meshes").mkdir()
    # a 1.2 m x 1 m guard panel standing on the table's far edge
    write_stl(tmp_path / "meshes" / "fence.stl", box_triangles((0.3, 0, 0.5), (1.2, 0.02, 1.0)))
    (tmp_path / "cells").mkdir()
    (tmp_path / "tasks").mkdir()
    (tmp_path / "cells" / "cell.yaml").write_text(cell)
    (tmp_path / "tasks" / "pick_place.yaml").write_text(task)
    (tmp_path / "tasks" / "home.yaml").write_text((ROOT / "tasks" / "home.yaml").read_text())
    r = cli("check", "cells/cell.yaml", "tasks/pick_place.yaml", "--json", cwd=tmp_path)
    assert r.returncode == 1, r.stdout[-3000:] + r.stderr[-2000:]
    out = json.loads(r.stdout)
    assert out["slots_checked"] == {"slot": list(range(12))}
    assert [f["slots"] for f in out["failed_slots"]] == [[8, 9, 10, 11]]
    assert all("nothing under it" in e and "'table'" in e for e in out["errors"])
    assert [e.split(":")[0] for e in out["errors"]] == [f"slot={k}" for k in (8, 9, 10, 11)]


def test_ur20_palletizer_through_ur_rtde():
    """`cellrunner run --backend ur` against `cellrunner twin` of the UR20 cell: the
    unmodified ur_rtde client streams the approved plan at 500 Hz to the virtual UR20."""
    from tests.rig import run_ur, twin

    cell, task, param, _, _ = CELLS["ur20"]
    host = "127.0.0.199"
    with twin(cell, host):
        out = run_ur(cell, task, host, "-p", f"{param}=5")
    assert out["result_code"] == 0, (out["result_text"], out["steps"])
    assert all(s["status"] == "ok" for s in out["steps"])
