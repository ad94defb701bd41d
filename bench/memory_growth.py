"""Where a long-running process's memory goes between two moments (the soak's ``--trace-memory``).

:class:`MemoryProbe` takes a baseline (``mark()``) and later reports what grew since:
Python allocations made since the mark and still alive, by source line (tracemalloc), live objects by
type (gc), and the C heap as glibc's allocator sees it (``mallinfo2``: bytes in use vs
free bytes kept in the heap), which tells growth of live data from fragmentation.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import gc
import tracemalloc
from collections import Counter
from typing import Any


class _MallInfo2(ctypes.Structure):
    _fields_ = [
        (name, ctypes.c_size_t)
        for name in (
            "arena",
            "ordblks",
            "smblks",
            "hblks",
            "hblkhd",
            "usmblks",
            "fsmblks",
            "uordblks",
            "fordblks",
            "keepcost",
        )
    ]


def malloc_mib() -> dict[str, float]:
    """glibc's heap (MiB): ``in_use`` (malloc'd, not freed), ``free`` (freed but kept in
    the arenas), ``mmapped`` (large blocks); empty where there is no mallinfo2."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        fn = libc.mallinfo2
    except (OSError, AttributeError):
        return {}
    fn.restype = _MallInfo2
    info = fn()
    mib = 1024 * 1024
    return {
        "in_use": info.uordblks / mib,
        "free": info.fordblks / mib,
        "mmapped": info.hblkhd / mib,
    }


def _type_counts() -> Counter[str]:
    gc.collect()
    return Counter(type(o).__qualname__ for o in gc.get_objects())


class MemoryProbe:
    """``mark()`` once (e.g. after 50 jobs), ``report()`` at the end. Allocations are
    traced from the mark on (tracing costs time on every allocation), so what the report
    lists by source line is what was allocated after the mark and is still alive."""

    def __init__(self, frames: int = 6) -> None:
        self._frames = frames
        self._types: Counter[str] = Counter()
        self._malloc: dict[str, float] = {}

    def mark(self) -> None:
        self._types = _type_counts()
        self._malloc = malloc_mib()
        tracemalloc.start(self._frames)

    def report(self, top: int = 15) -> dict[str, Any]:
        """What grew since ``mark()``: lines (KiB, count), types (count), heap (MiB)."""
        assert tracemalloc.is_tracing(), "mark() first"
        types = _type_counts()
        snapshot = tracemalloc.take_snapshot()
        tracemalloc.stop()
        stats = snapshot.filter_traces(
            [tracemalloc.Filter(False, tracemalloc.__file__)]
        ).statistics("traceback")
        lines = [
            {
                "kib": st.size / 1024,
                "count": st.count,
                "where": [f"{f.filename}:{f.lineno}" for f in st.traceback][-4:],
            }
            for st in stats[:top]
        ]
        grown = Counter({k: types[k] - self._types.get(k, 0) for k in types})
        return {
            "traced_mib": sum(st.size for st in stats) / 2**20,
            "lines": lines,
            "types": dict(grown.most_common(top)),
            "malloc_mib": {"mark": self._malloc, "end": malloc_mib()},
        }


def print_report(report: dict[str, Any], out: Any) -> None:
    print(
        f"allocated since the mark and still alive: {report['traced_mib']:.1f} MiB, "
        "by allocation site:",
        file=out,
    )
    for line in report["lines"]:
        print(f"  {line['kib']:+9.1f} KiB {line['count']:+7d}  {line['where'][-1]}", file=out)
        for frame in reversed(line["where"][:-1]):
            print(f"{'':27}<- {frame}", file=out)
    print(f"grown live objects by type: {report['types']}", file=out)
    heap = report["malloc_mib"]
    if heap["end"]:
        print(
            "C heap (MiB): "
            + ", ".join(
                f"{k} {heap['mark'].get(k, float('nan')):.1f} -> {v:.1f}"
                for k, v in heap["end"].items()
            ),
            file=out,
        )
