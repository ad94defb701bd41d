"""One trip per job: a dry-run expands each job's steps once (plan, twin, feed and
rehearsal share them) and reads each file once."""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import Any

import pytest

import cellrunner.model.expand as expand_module
import cellrunner.model.load as load_module
from tests.rig import main_json

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def counted(monkeypatch: pytest.MonkeyPatch) -> tuple[Counter[str], Counter[str]]:
    """(expansions per task and params, reads per resolved file), counted in-process."""
    expansions: Counter[str] = Counter()
    reads: Counter[str] = Counter()
    expand, load_yaml = expand_module.expand, load_module.load_yaml

    def counting_expand(task: Any, cell: Any, params: Any) -> Any:
        expansions[f"{task.name} {sorted(params.items())}"] += 1
        return expand(task, cell, params)

    def counting_load_yaml(path: Path) -> Any:
        reads[str(Path(path).resolve())] += 1
        return load_yaml(path)

    monkeypatch.setattr(expand_module, "expand", counting_expand)
    monkeypatch.setattr(load_module, "load_yaml", counting_load_yaml)
    return expansions, reads


def test_a_dry_run_expands_each_job_once_and_reads_each_file_once(
    counted: tuple[Counter[str], Counter[str]], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(ROOT)
    expansions, reads = counted
    code, out = main_json("dry-run", "cells/cnc_tending_ur5e.yaml", "tasks/cnc_tend.yaml")
    assert code == 0 and out["result_code"] == 0, out
    assert expansions and max(expansions.values()) == 1, expansions
    assert reads and max(reads.values()) == 1, reads
