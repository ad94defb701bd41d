"""A journal's job rows as the program reads them (:class:`JobRecord`), and the column
that keeps a refused job's typed failure (JSON of
:meth:`~cellrunner.model.failure.Failure.to_json`); both journals read and write through
these, so the two agree on the row and on the failure."""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

from cellrunner.model.failure import Failure


@dataclass(frozen=True)
class JobRecord:
    job_id: str
    client_job_id: str | None
    cell: str
    task: str
    params: dict[str, Any]
    source: str
    started_at: float
    ended_at: float | None
    result_code: int | None
    result_text: str | None
    cycle_time_s: float | None
    retries: int
    #: why the planner refused the job, as data (None: any other end, or an old journal)
    failure: Failure | None = None


def record_of(row: tuple[Any, ...]) -> JobRecord:
    """A job read back: its columns in :class:`JobRecord`'s order, ``params`` as JSON
    text or already decoded, ``failure`` as :func:`failure_json` wrote it."""
    params = row[4] if isinstance(row[4], dict) else json.loads(row[4])
    job_id, client_job_id, cell, task, _, source, started, ended, code, text, cycle, retries = row[
        :12
    ]
    return JobRecord(
        job_id,
        client_job_id,
        cell,
        task,
        params,
        source,
        started,
        ended,
        code,
        text,
        cycle,
        retries,
        failure_of(row[12]),
    )


def failure_json(failure: Failure | None) -> str | None:
    """The ``failure`` column's value of a job's end."""
    return None if failure is None else json.dumps(failure.to_json(), sort_keys=True)


def failure_of(column: str | None) -> Failure | None:
    """The failure the ``failure`` column holds; None when empty or not one (a value
    another version wrote is left unread rather than stopping the journal's reads)."""
    if not column:
        return None
    try:
        return Failure.from_json(json.loads(column))
    except (ValueError, KeyError, TypeError):  # from_json's contract on foreign data
        return None
