"""Files cellrunner writes (the journal, the PKI folder) belong to the cell's project, never
to the folder a command happens to run from."""

from __future__ import annotations

from pathlib import Path

import pytest

from cellrunner.model.load import load_cell
from tests.rig import CELL


def _project(folder: Path) -> Path:
    (folder / "cells").mkdir(parents=True)
    cell = folder / "cells" / "c.yaml"
    cell.write_text(CELL)  # no journal: written: var/jobs.sqlite, relative
    return cell


def test_a_journal_in_the_working_directory_is_not_taken_over(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    elsewhere = tmp_path / "elsewhere"
    (elsewhere / "var").mkdir(parents=True)
    (elsewhere / "var" / "jobs.sqlite").write_bytes(b"")  # another project's journal
    monkeypatch.chdir(elsewhere)
    cell = load_cell(_project(tmp_path / "line3"))
    assert cell.resolve_output("var/jobs.sqlite") == tmp_path / "line3" / "var" / "jobs.sqlite"
    # files the cell reads still fall back to the working directory, as before
    assert cell.resolve("var/jobs.sqlite") == elsewhere / "var" / "jobs.sqlite"


def test_an_existing_journal_beside_the_cell_file_is_kept(tmp_path: Path) -> None:
    cell_path = _project(tmp_path / "line3")
    beside = cell_path.parent / "var" / "jobs.sqlite"
    beside.parent.mkdir()
    beside.write_bytes(b"")
    assert load_cell(cell_path).resolve_output("var/jobs.sqlite") == beside
    (tmp_path / "line3" / "var").mkdir()
    (tmp_path / "line3" / "var" / "jobs.sqlite").write_bytes(b"")  # the root's comes first
    assert load_cell(cell_path).resolve_output("var/jobs.sqlite") == (
        tmp_path / "line3" / "var" / "jobs.sqlite"
    )


def test_an_absolute_path_is_itself(tmp_path: Path) -> None:
    cell = load_cell(_project(tmp_path / "line3"))
    assert cell.resolve_output(str(tmp_path / "j.sqlite")) == tmp_path / "j.sqlite"
