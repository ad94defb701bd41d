"""A hole modelled as an STL mesh: the twin builds a non-convex mesh from its triangles (a
hull would fill the hole), so the peg goes in as in the cell built from boxes."""

from __future__ import annotations

from tests.cells.meshes import box_triangles, write_stl
from tests.cells.reference import PEG
from tests.conftest import ROOT
from tests.rig import dry_run

#: the block around the hole, as (centre, size) boxes: four walls and the floor (m)
BOXES = [
    ((0.2695, 0.15, 0.82), (0.039, 0.10, 0.04)),
    ((0.3305, 0.15, 0.82), (0.039, 0.10, 0.04)),
    ((0.30, 0.1195, 0.82), (0.022, 0.039, 0.04)),
    ((0.30, 0.1805, 0.82), (0.022, 0.039, 0.04)),
    ((0.30, 0.15, 0.805), (0.022, 0.022, 0.01)),
]


def test_peg_goes_into_a_mesh_hole(tmp_path):
    (tmp_path / "cells").mkdir()
    (tmp_path / "tasks").mkdir()
    write_stl(tmp_path / "hole_block.stl", [t for b in BOXES for t in box_triangles(*b)])
    lines = [
        ln
        for ln in (ROOT / PEG[0]).read_text().splitlines(keepends=True)
        if not ln.lstrip().startswith(("- {name: wall_", "- {name: hole_floor"))
    ]
    cell = "".join(lines).replace(
        "fixtures:\n", "fixtures:\n  - {name: block, mesh: {file: hole_block.stl}}\n"
    )
    (tmp_path / "cells" / "peg.yaml").write_text(cell)
    (tmp_path / "tasks" / "peg_insert.yaml").write_text((ROOT / PEG[1]).read_text())
    out = dry_run(str(tmp_path / "cells" / "peg.yaml"), str(tmp_path / "tasks" / "peg_insert.yaml"))
    assert out["result_code"] == 0, (out["result_text"], out["steps"])
    assert out["parts_end_m"]["peg"][2] < 0.87  # in the hole, not on the block
