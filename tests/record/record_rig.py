"""The recordings' test rig: a journal of the test's own, and a recording's columns."""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path


def own_journal(tmp_path: Path) -> str:
    """A journal of the test's own (a relative one may resolve to one in the working
    directory, which other tests count jobs in)."""
    return f"journal: {tmp_path / 'var' / 'jobs.sqlite'}\n"


def rrd_columns(path: Path) -> tuple[dict[str, set[str]], dict[str, list[list[float]]]]:
    """Components by entity path, and each entity's poses (translation, then the 3x3
    rotation) in time order."""
    from rerun.chunk import RrdReader

    components: dict[str, set[str]] = defaultdict(set)
    moves: dict[str, list[tuple[int, list[float]]]] = defaultdict(list)
    for chunk in RrdReader(path).store().stream():
        batch = chunk.to_record_batch()
        components[chunk.entity_path] |= set(batch.schema.names)
        if "Transform3D:translation" in batch.schema.names and "time" in batch.schema.names:
            times = batch.column("time").to_pylist()
            translations = batch.column("Transform3D:translation").to_pylist()
            rotations = batch.column("Transform3D:mat3x3").to_pylist()
            for t, p, r in zip(times, translations, rotations, strict=True):
                moves[chunk.entity_path].append((t, [*p[0], *r[0]]))
    ordered = {
        path: [p for _, p in sorted(rows, key=lambda r: r[0])] for path, rows in moves.items()
    }
    return components, ordered
