"""Opening the journal a cell file names: SQLite or PostgreSQL (see
:mod:`cellrunner.execution.journal`)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from cellrunner.execution.journal import POSTGRES_SCHEMES, JournalBackend, SqliteJournal
from cellrunner.execution.journal_postgres import PostgresJournal
from cellrunner.model.load import LoadedCell


def journal_for(
    location: str, cell: str | None, resolve: Callable[[str], Path] = Path
) -> JournalBackend:
    """The journal the cell file's ``journal:`` names: a ``postgresql://`` URL, else a
    SQLite file (``resolve`` turns the written path into a file path)."""
    if location.startswith(POSTGRES_SCHEMES):
        return PostgresJournal(location, cell)
    return SqliteJournal(resolve(location), cell)


def cell_journal(cell: LoadedCell, *, all_cells: bool = False) -> JournalBackend:
    """The journal of a loaded cell (``LoadedCell``); ``all_cells`` reads every cell's jobs."""
    return journal_for(
        cell.cell.journal, None if all_cells else cell.cell.cell, cell.resolve_output
    )
