"""check and the twin against the truth of generated cells (bench/cellgen.py, issue 33):
the generator is reproducible and its witnesses are real, and on a fixed sample every
job is classified as the truth says (no false approval, no twin false OK, no false
refusal)."""

from __future__ import annotations

import numpy as np
import pytest

from bench.agreement import DISAGREEMENTS, classify, judge
from bench.cellgen import (
    ADDED_KINDS,
    DEFECTS,
    FEASIBLE,
    KINDS,
    LATER_FEASIBLE,
    MOUNTS,
    PLAIN_KINDS,
    corpus,
    generate,
)
from bench.cellgen_cameras import CAMERA_KINDS

#: the fixed sample scripts/test runs: each kind on its own seeds (jaws and cups, and the
#: holes: a fit, a hole too shallow, a rim and an interference jam); with the dry-runs
#: of the approved jobs, over 40 runs of check and the twin
SAMPLE_SEED, SAMPLE_SIZE = 5000, 39
#: and one job of each kind with a camera (bench/cellgen_cameras.py), on its own seeds
CAMERA_SEED = 5100
#: and three of each kind added since (an interlocked pallet's turned upper layer, a
#: part that slips out in transit and the on_error that clears up after it)
LATER_SEED, LATER_EACH = 5200, 3
#: and one of each kind added after those: the declared press fits (one that presses in,
#: one loose, one too tight), a blocked column (a pitch under the part's width) and each
#: hole kind with chamfered walls (bench/cellgen_chamfers.py)
ADDED_SEED, ADDED_EACH = 5300, 1


def sample() -> list:
    """The fixed sample: the plain kinds' jobs, one of each camera kind, then the kinds
    added since and the chamfered holes."""
    return [
        *corpus(SAMPLE_SIZE, SAMPLE_SEED, PLAIN_KINDS),
        *corpus(len(CAMERA_KINDS), CAMERA_SEED, CAMERA_KINDS),
        *corpus(LATER_EACH * len(LATER_FEASIBLE), LATER_SEED, LATER_FEASIBLE),
        *corpus(ADDED_EACH * len(ADDED_KINDS), ADDED_SEED, ADDED_KINDS),
    ]


#: disagreements the harness found that are not fixed yet, each with its cause
#: (docs/check-truth.md): the test fails on any other, and on one of these that is gone.
#: Fixed: s5025 (a UR10e's set-down at full speed pressed the part into its table; a
#: place's descend is now timed gently); s5003 and s5016 (the pin crept 1-3 mm in the
#: twin's jaws as it was carried and met the rim: the jaws' weld holds it now)
KNOWN_OPEN: dict[str, str] = {}


def test_the_same_seed_writes_the_same_files_and_another_seed_others():
    a, b = generate(7, "near_support"), generate(7, "near_support")
    assert (a.cell, a.task) == (b.cell, b.task)
    assert generate(8, "near_support").cell != a.cell
    with pytest.raises(ValueError, match="unknown case kind 'warped'; known: feasible"):
        generate(7, "warped")


def test_each_witness_puts_the_tcp_on_its_frame_within_the_joint_limits():
    from bench.cellgen import _kinematics

    for case in corpus(6, 300):
        tcp_m = case.cell["tool"]["tcp"]["xyz"][2]
        mount = _mount(case)
        kin = _kinematics(case.cell["robot"]["model"], tcp_m, mount)
        place = "hole" if "hole" in case.cell["frames"] else "outfeed"  # (cellgen_holes)
        for frame, witness in (("infeed", "pick"), (place, "place")):
            if case.kind in ("out_of_reach", "jam_rim") and witness == "place":
                continue  # moved on purpose (out of reach, over the rim): no witness
            q = np.radians(case.witness_deg[witness])
            assert np.all(q >= kin.q_min_rad) and np.all(q <= kin.q_max_rad)
            T = kin.T_world_tcp(q)
            xyz = case.cell["frames"][frame]["xyz"]
            assert np.allclose(T[:3, 3], xyz, atol=1e-4), (case.name, frame)


def _mount(case) -> str:
    rpy = tuple(case.cell["robot"]["mount"]["rpy"])
    return next(name for name, (_, mount_rpy, _) in MOUNTS.items() if mount_rpy == rpy)


def test_the_classes():
    assert classify(True, 0, 0) == "true accept"
    assert classify(True, 1, None) == "false refusal"
    assert classify(True, 0, 100) == "false approval"
    assert classify(False, 1, None) == "true refuse"
    assert classify(False, 0, 3) == "false approval"
    assert classify(False, 0, 0) == "twin false OK"
    assert classify(False, 2, None) == "invalid file"
    assert classify(True, 0, None) == "twin did not run"
    # a rehearsal that injects a fault must end with its code, on_error done
    assert classify(True, 0, 2, expect_code=2) == "true accept"
    assert classify(True, 0, 2, expect_code=2, recovered=False) == "false approval"
    assert classify(True, 0, 0, expect_code=2) == "false approval"


def test_a_fixed_sample_agrees_with_the_truth(tmp_path):
    verdicts = [judge(case, tmp_path) for case in sample()]
    runs = len(verdicts) + sum(1 for v in verdicts if v.result_code is not None)
    assert runs >= 40
    assert {v.kind for v in verdicts} == set(KINDS)
    cases = sample()
    assert {c.cell["tool"]["gripper"]["kind"] for c in cases} == {"io", "vacuum"}
    assert {_mount(c) for c in cases} == set(MOUNTS)  # floor, ceiling, wall
    wrong = {v.name: f"{v.verdict}: {v.message}" for v in verdicts if v.verdict in DISAGREEMENTS}
    assert sorted(wrong) == sorted(KNOWN_OPEN), wrong
    for name, why in KNOWN_OPEN.items():
        assert wrong[name].startswith(why.split(":")[0]), (name, wrong[name])
    right = [v for v in verdicts if v.name not in KNOWN_OPEN]
    assert all(v.verdict == "true accept" for v in right if v.kind in FEASIBLE)
    assert all(v.verdict == "true refuse" for v in right if v.kind in DEFECTS)
