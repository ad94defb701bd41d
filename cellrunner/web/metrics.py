"""Prometheus metrics of one cell, in the text exposition format (version 0.0.4).

Written by hand (a few families), so the cell needs no metrics library and keeps no
process-wide registry: :class:`JobMetrics` counts the jobs this process finished, and
:func:`render` writes them with a status snapshot.
"""

from __future__ import annotations

import bisect
import threading
from collections.abc import Iterable

from cellrunner.model.cellport import CellStatus, JobResult
from cellrunner.model.codes import PackMLState, ResultCode

CONTENT_TYPE = "text/plain; version=0.0.4; charset=utf-8"

#: cycle time histogram bucket upper bounds, s
CYCLE_BUCKETS_S = (1.0, 2.0, 5.0, 10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 90.0, 120.0, 300.0)


class JobMetrics:
    """Jobs finished by this process: a counter per result code and a cycle time
    histogram. :meth:`record` is a result listener (any thread, never blocks long)."""

    def __init__(self, buckets_s: Iterable[float] = CYCLE_BUCKETS_S) -> None:
        self.buckets_s = tuple(sorted(buckets_s))
        self._lock = threading.Lock()
        self._by_code: dict[ResultCode, int] = {}
        self._bucket_counts = [0] * (len(self.buckets_s) + 1)  # the last is +Inf
        self._cycle_sum_s = 0.0

    def record(self, result: JobResult) -> None:
        with self._lock:
            self._by_code[result.result_code] = self._by_code.get(result.result_code, 0) + 1
            if result.cycle_time_s and result.cycle_time_s > 0:
                self._bucket_counts[bisect.bisect_left(self.buckets_s, result.cycle_time_s)] += 1
                self._cycle_sum_s += result.cycle_time_s

    def snapshot(self) -> tuple[dict[ResultCode, int], list[int], float]:
        with self._lock:
            return dict(self._by_code), list(self._bucket_counts), self._cycle_sum_s


Sample = tuple[str, dict[str, str], float]
"""One sample of a family: the name's suffix (``_bucket``...), its own labels, the value."""

Family = tuple[str, str, str, list[Sample]]
"""One metric family: name, type (``counter``, ``gauge``, ``histogram``), HELP text, samples."""


def render(cell: str, status: CellStatus, jobs: JobMetrics, plc_links: dict[str, bool]) -> str:
    """The metrics page: every family with its HELP and TYPE lines, each sample labelled
    with the cell's name."""
    families = [*_job_families(jobs), *_status_families(status), _plc_family(plc_links)]
    out: list[str] = []
    for family in families:
        out += _family_lines(family, {"cell": cell})
    return "\n".join(out) + "\n"


def _family_lines(family: Family, base: dict[str, str]) -> list[str]:
    """The HELP, TYPE and sample lines of one family; ``base`` labels come first on each."""
    name, kind, help_text, samples = family
    out = [f"# HELP {name} {help_text}", f"# TYPE {name} {kind}"]
    for suffix, labels, value in samples:
        out.append(f"{name}{suffix}{_labels({**base, **labels})} {_number(value)}")
    return out


def _job_families(jobs: JobMetrics) -> list[Family]:
    """The jobs counter by result code (OK always listed) and the cycle time histogram (s)."""
    by_code, buckets, cycle_sum_s = jobs.snapshot()
    codes = sorted(set(by_code) | {ResultCode.OK})
    jobs_total: Family = (
        "cellrunner_jobs_total",
        "counter",
        "Jobs finished since cellrunner started, by result code (SPEC 7).",
        [("", {"code": str(int(c)), "result": c.text}, by_code.get(c, 0)) for c in codes],
    )
    cumulative = 0
    samples: list[Sample] = []
    for bound, count in zip([*jobs.buckets_s, float("inf")], buckets, strict=True):
        cumulative += count
        samples.append(("_bucket", {"le": _number(bound)}, cumulative))
    samples += [("_sum", {}, cycle_sum_s), ("_count", {}, cumulative)]
    cycle_time: Family = (
        "cellrunner_cycle_time_seconds",
        "histogram",
        "Cycle time of finished jobs, s.",
        samples,
    )
    return [jobs_total, cycle_time]


def _status_families(status: CellStatus) -> list[Family]:
    """The cell's state: PackML state, flags (1 or 0), the step under way, the part counters."""

    def single(name: str, kind: str, help_text: str, value: float) -> Family:
        return (name, kind, help_text, [("", {}, value)])

    state_name = PackMLState(status.state).display_name
    return [
        single(
            "cellrunner_packml_state", "gauge", "PackML StateCurrent number (SPEC 6).", status.state
        ),
        (
            "cellrunner_packml_state_info",
            "gauge",
            "1 for the current PackML state.",
            [("", {"state": state_name}, 1)],
        ),
        single("cellrunner_busy", "gauge", "1 while a job runs.", int(status.busy)),
        single(
            "cellrunner_ready", "gauge", "1 while the cell would accept a job.", int(status.ready)
        ),
        single(
            "cellrunner_protective_stop",
            "gauge",
            "1 during a protective stop.",
            int(status.protective_stop),
        ),
        single(
            "cellrunner_estop", "gauge", "1 while the emergency stop is pressed.", int(status.estop)
        ),
        single(
            "cellrunner_current_step",
            "gauge",
            "1-based expanded step under way, 0 when none.",
            status.step_index,
        ),
        single(
            "cellrunner_parts_processed_total",
            "counter",
            "Parts processed (OK jobs) in the journal.",
            status.parts_processed,
        ),
        single(
            "cellrunner_parts_defective_total",
            "counter",
            "Jobs that ended NOK (codes 1-3) in the journal.",
            status.parts_defective,
        ),
    ]


def _plc_family(plc_links: dict[str, bool]) -> Family:
    """1 or 0 per PLC link, by the link's name."""
    return (
        "cellrunner_plc_link_up",
        "gauge",
        "1 while the PLC link is up (Modbus: heartbeat moving; OPC UA: a client connected).",
        [("", {"link": name}, int(up)) for name, up in sorted(plc_links.items())],
    )


def _labels(labels: dict[str, str]) -> str:
    if not labels:
        return ""
    body = ",".join(f'{k}="{_escape(str(v))}"' for k, v in labels.items())
    return "{" + body + "}"


def _escape(value: str) -> str:
    return value.replace("\\", "\\\\").replace("\n", "\\n").replace('"', '\\"')


def _number(value: float) -> str:
    if value == float("inf"):
        return "+Inf"
    if float(value).is_integer():
        return str(int(value)) if abs(value) < 1e15 else repr(float(value))
    return repr(float(value))
