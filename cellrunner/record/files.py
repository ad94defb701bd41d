"""Which writer a recording file gets (by its suffix), and ``serve``'s folder of
recordings: one file per job named by its job id, the oldest removed once the folder
holds more than its size cap (as the journal keeps its size)."""

from __future__ import annotations

import re
from pathlib import Path

from cellrunner.errors import UsageError
from cellrunner.record.sink import Sink

#: the suffixes ``--record`` writes
SUFFIXES = (".rrd", ".mcap")

#: a folder of recordings keeps at most this much by default (MB)
DEFAULT_MAX_MB = 2048.0


def check_target(path: str) -> Path:
    """``--record FILE``'s file: .rrd or .mcap in a folder that exists (a UsageError, exit
    2, otherwise), its writer's library installed."""
    target = Path(path)
    if target.suffix not in SUFFIXES:
        raise UsageError(
            f"--record {path}: a recording is FILE.rrd (Rerun) or FILE.mcap (Foxglove)"
        )
    if not target.parent.is_dir():
        raise UsageError(f"--record {path}: no folder {target.parent}")
    need_library(target.suffix)
    return target


def need_library(suffix: str) -> None:
    """A UsageError naming the extra to install when the writer of ``suffix`` is missing."""
    import importlib.util

    modules = (
        ("rerun",) if suffix == ".rrd" else ("mcap", "mcap_protobuf", "foxglove_schemas_protobuf")
    )
    missing = [m for m in modules if importlib.util.find_spec(m) is None]
    if missing:
        raise UsageError(
            f"recording {suffix} needs {', '.join(missing)}: pip install 'cellrunner[record]'"
        )


def warm_up(suffix: str) -> None:
    """Import the writer of ``suffix`` now (the recorder's worker, before any job), not
    as the first job starts: an import holds the GIL for a long while."""
    if suffix == ".mcap":
        import cellrunner.record.mcap_file as mcap_file

        mcap_file._messages()
    else:
        import rerun  # noqa: F401


def open_sink(path: Path, name: str) -> Sink:
    """A writer for ``path`` by its suffix."""
    if path.suffix == ".mcap":
        from cellrunner.record.mcap_file import McapSink

        return McapSink(path, name)
    from cellrunner.record.rrd import RerunSink

    return RerunSink(path, name)


class JobFolder:
    """``serve --record DIR``: ``DIR/<job id>.rrd`` (or ``.mcap``), the oldest files removed
    while the folder holds more than ``max_mb``."""

    def __init__(self, folder: Path, max_mb: float = DEFAULT_MAX_MB, suffix: str = ".rrd") -> None:
        self.folder, self.max_bytes, self.suffix = folder, int(max_mb * 1e6), suffix

    def open(self, job_id: str) -> Sink:
        self.prune()
        return open_sink(self.path_of(job_id), job_id)

    def path_of(self, job_id: str) -> Path:
        """``DIR/<job id>.rrd``; ``<job id>-2.rrd`` and on when a PLC reused the id."""
        name = re.sub(r"[^A-Za-z0-9_.-]+", "_", job_id) or "job"
        path, n = self.folder / f"{name}{self.suffix}", 1
        while path.exists():
            n += 1
            path = self.folder / f"{name}-{n}{self.suffix}"
        return path

    @staticmethod
    def check(folder: str, suffix: str) -> Path:
        """``serve --record DIR``: the folder (made if missing); a UsageError when it
        cannot be or the writer's library is missing."""
        path = Path(folder)
        try:
            path.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise UsageError(f"--record {folder}: cannot make the folder ({exc.strerror})") from exc
        need_library(suffix)
        return path

    def prune(self) -> list[Path]:
        """Remove the oldest recordings beyond the cap; the removed files."""
        files = sorted(
            (p for p in self.folder.iterdir() if p.suffix in SUFFIXES),
            key=lambda p: p.stat().st_mtime,
        )
        total = sum(p.stat().st_size for p in files)
        removed = []
        while files and total > self.max_bytes:
            oldest = files.pop(0)
            total -= oldest.stat().st_size
            oldest.unlink(missing_ok=True)
            removed.append(oldest)
        return removed
