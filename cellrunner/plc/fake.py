"""``FakeCell``: a scripted, in-process :class:`~cellrunner.plc.port.CellPort`.

It stands in for the execution engine in PLC tests and the soak bench: jobs take
scripted step durations and end with scripted result codes, and the PackML state
moves as SPEC section 6 says (Idle -> Starting -> Execute -> Completing -> Complete
-> Resetting -> Idle; Hold -> Holding/Held; Abort or e-stop -> Aborting/Aborted,
Clear -> Stopped, Reset -> Idle). Nothing moves a robot.

Lifecycle: construct (no thread) -> ``start()`` -> ... -> ``close()``.
"""

from __future__ import annotations

import itertools
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from datetime import UTC, datetime

from cellrunner.model.hold_source import HoldSource
from cellrunner.plc.port import (
    COMMANDS,
    COMPLETED_CODES,
    ArmStatus,
    CellStatus,
    JobResult,
    JobSource,
    JobTicket,
    PackMLState,
    ResultCode,
    ResultListener,
)

S = PackMLState

#: How long the fake spends in each transient PackML state, s.
TRANSIENT_S = 0.01


@dataclass(frozen=True)
class FakeParam:
    """A typed, bounded task parameter (as a task file's ``params:`` entry)."""

    name: str
    type: str = "int"  # "int" | "float"
    min: float = -32768
    max: float = 32767
    default: float = 0


@dataclass(frozen=True)
class FakeTask:
    """A task the fake knows: number, name, params in order, step durations in s."""

    number: int
    name: str
    params: tuple[FakeParam, ...] = ()
    step_durations_s: tuple[float, ...] = (0.02, 0.02, 0.02)


@dataclass
class _Job:
    job_id: str
    task: FakeTask
    params: dict[str, int | float]
    client_job_id: str
    source: str
    result_code: ResultCode
    started_s: float
    step_index: int = 0
    step_left_s: float = 0.0
    retries: int = 0
    end_code: ResultCode | None = None

    def result(self, code: ResultCode, now_s: float) -> JobResult:
        """This job's result, ended now (clock time ``now_s``) with ``code``."""
        return JobResult(
            job_id=self.job_id,
            result_code=code,
            result_text=_result_text(code),
            cycle_time_s=now_s - self.started_s,
            end_time=datetime.now(UTC),
            retries=1 if code == ResultCode.NO_PART else 0,
            task=self.task.name,
            client_job_id=self.client_job_id,
            source=self.source,
        )


@dataclass
class _Injected:
    protective_stop: bool = False
    estop: bool = False


class _Fanout:
    """The result listeners and the results not yet told to them (told outside the
    cell's lock, so a listener may call back into the cell)."""

    def __init__(self, lock: threading.RLock) -> None:
        self._lock = lock
        self._listeners: list[ResultListener] = []
        self.pending: list[JobResult] = []

    def add(self, listener: ResultListener) -> Callable[[], None]:
        with self._lock:
            self._listeners.append(listener)

        def remove() -> None:
            with self._lock:
                if listener in self._listeners:
                    self._listeners.remove(listener)

        return remove

    def notify(self) -> None:
        with self._lock:
            pending, self.pending = self.pending, []
            listeners = list(self._listeners)
        for result in pending:
            for listener in listeners:
                listener(result)


def default_tasks() -> list[FakeTask]:
    """The tasks of the example cell: 1 pick_place(slot 0..11), 2 home."""
    return [
        FakeTask(1, "pick_place", (FakeParam("slot", "int", 0, 11, 0),)),
        FakeTask(2, "home", (), (0.02,)),
    ]


@dataclass
class FakeCell:
    """Scripted cell engine.

    ``results`` gives the result code of each accepted job in turn (default 0 once
    exhausted); ``result_fn(task_name, params)`` overrides it when set.
    ``last_result`` seeds the last result, e.g. a job closed with 107 at start-up.
    """

    tasks: list[FakeTask] = field(default_factory=default_tasks)
    results: Iterable[int] = ()
    result_fn: Callable[[str, dict[str, int | float]], int] | None = None
    last_result: JobResult | None = None
    parts_processed: int = 0
    parts_defective: int = 0
    tick_s: float = 0.002
    clock: Callable[[], float] = time.monotonic  # the one time source, s (tests inject theirs)

    def __post_init__(self) -> None:
        self._by_number = {t.number: t for t in self.tasks}
        self._by_name = {t.name: t for t in self.tasks}
        self._script = deque(self.results)
        self._lock = threading.RLock()
        self._state = S.IDLE
        self._state_until_s = 0.0
        self._next_state: PackMLState | None = None
        self._job: _Job | None = None
        self._queued: _Job | None = None
        self._ids = itertools.count(1)
        self._fanout = _Fanout(self._lock)
        self._injected = _Injected()
        self._processed = self.parts_processed
        self._defective = self.parts_defective
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._last_tick_s = 0.0
        self.finished: list[JobResult] = []  # every result, in order (the "journal")
        self.commands: list[str] = []  # every accepted command, in order
        self.sources: list[HoldSource] = []  # who asked each of them
        self._hold_source: HoldSource | None = None  # who held the job held now

    # -- lifecycle -----------------------------------------------------------------
    def start(self) -> FakeCell:
        if self._thread is None:
            self._stop.clear()
            self._thread = threading.Thread(target=self._run, name="fake-cell", daemon=True)
            self._thread.start()
        return self

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None

    def __enter__(self) -> FakeCell:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- CellPort ------------------------------------------------------------------
    def status(self) -> CellStatus:
        with self._lock:
            job = self._job or self._queued
            state = self._state
            held = state in (S.HOLDING, S.HELD, S.UNHOLDING)
            return CellStatus(
                state=int(state),
                state_name=state.display_name,
                ready=self._is_ready(),
                busy=job is not None,
                held=held,
                protective_stop=self._injected.protective_stop,
                estop=self._injected.estop,
                job_id=job.job_id if job else "",
                step_index=job.step_index if job else 0,
                last_result=self.last_result,
                parts_processed=self._processed,
                parts_defective=self._defective,
                hold_source=self._hold_source.value if held and self._hold_source else "",
                hold_reason=self._hold_source.reason if held and self._hold_source else "",
            )

    def arm(self) -> ArmStatus:
        """A UR5e whose base joint turns at 0.5 rad/s while a job runs (an ArmPort)."""
        with self._lock:
            return _arm_status(self._job, self._injected, self.clock())

    def finished_job(self, source: str, client_job_id: str) -> JobResult | None:
        """The first finished job ``source`` named ``client_job_id`` (a JobHistory: the
        ``finished`` list is this cell's journal)."""
        with self._lock:
            for result in self.finished:
                if result.source == source and result.client_job_id == client_job_id:
                    return result
            return None

    def task_names(self) -> list[str]:
        return [t.name for t in sorted(self.tasks, key=lambda t: t.number)]

    def task_params(self, task: str | int) -> list[str] | None:
        found = self._find_task(task)
        return None if found is None else [p.name for p in found.params]

    def start_job(
        self,
        task: str | int,
        params: dict[str, int | float],
        client_job_id: str,
        source: str | JobSource = "",
    ) -> JobTicket:
        found = self._find_task(task)
        if found is None:
            known = ", ".join(f"{t.number} {t.name}" for t in self.tasks)
            return JobTicket(
                "", ResultCode.REJECT_UNKNOWN_TASK, f"unknown task {task!r}; known: {known}"
            )
        error = _check_params(found, params)
        if error:
            return JobTicket("", ResultCode.REJECT_BAD_PARAMS, error)
        with self._lock:
            if not self._is_ready():
                return JobTicket(
                    "", ResultCode.REJECT_NOT_READY, f"not ready: state {self._state.display_name}"
                )
            full = {p.name: params.get(p.name, p.default) for p in found.params}
            code = self._next_result(found.name, full)
            job = _Job(
                job_id=f"J{next(self._ids):06d}",
                task=found,
                params=full,
                client_job_id=client_job_id,
                source=JobSource.of(source).name,
                result_code=code,
                started_s=self.clock(),
            )
            self._queued = job
            self._enter(S.STARTING, S.EXECUTE)
            return JobTicket(job.job_id)

    def command(self, name: str, source: HoldSource = HoldSource.PLC) -> bool:
        if name not in COMMANDS:
            raise ValueError(f"unknown command {name!r}; known: {', '.join(COMMANDS)}")
        with self._lock:
            accepted = self._apply_command(name)
            if accepted and name == "hold":
                self._hold_source = source
            if accepted:
                self.commands.append(name)
                self.sources.append(source)
            return accepted

    def add_result_listener(self, listener: ResultListener) -> Callable[[], None]:
        return self._fanout.add(listener)

    # -- fault injection (what the twin's physics would cause) --------------------------
    def inject_protective_stop(self) -> None:
        with self._lock:
            self._injected.protective_stop = True
            if self._state in (S.EXECUTE, S.STARTING, S.UNHOLDING):
                self._enter(S.HOLDING, S.HELD)

    def release_protective_stop(self, *, unhold: bool = True) -> None:
        with self._lock:
            self._injected.protective_stop = False
            if unhold and self._state == S.HELD:
                self._enter(S.UNHOLDING, S.EXECUTE)

    def inject_estop(self) -> None:
        with self._lock:
            self._injected.estop = True
            self._abort(ResultCode.ESTOP)

    def release_estop(self) -> None:
        with self._lock:
            self._injected.estop = False

    # -- internals -----------------------------------------------------------------
    def _find_task(self, task: str | int) -> FakeTask | None:
        if isinstance(task, int):
            return self._by_number.get(task)
        if task.strip().isdigit():
            return self._by_number.get(int(task))
        return self._by_name.get(task)

    def _next_result(self, name: str, params: dict[str, int | float]) -> ResultCode:
        """The scripted code of the next job (a test's number, a SPEC code)."""
        if self.result_fn is not None:
            return ResultCode(self.result_fn(name, params))
        return ResultCode(self._script.popleft() if self._script else 0)

    def _is_ready(self) -> bool:
        return (
            self._state == S.IDLE
            and self._job is None
            and self._queued is None
            and not self._injected.estop
            and not self._injected.protective_stop
        )

    def _enter(self, state: PackMLState, then: PackMLState | None = None) -> None:
        self._state = state
        self._next_state = then
        self._state_until_s = self.clock() + TRANSIENT_S

    def _apply_command(self, name: str) -> bool:
        st = self._state
        if name == "hold" and st in (S.EXECUTE, S.STARTING, S.UNHOLDING):
            self._enter(S.HOLDING, S.HELD)
        elif name == "unhold" and st == S.HELD and not self._injected.protective_stop:
            self._enter(S.UNHOLDING, S.EXECUTE)
        elif name == "abort" and st not in (S.ABORTING, S.ABORTED, S.CLEARING):
            self._abort(ResultCode.ABORTED_BY_PLC)
        elif name == "clear" and st == S.ABORTED and not self._injected.estop:
            self._enter(S.CLEARING, S.STOPPED)
        elif name == "reset" and st in (S.STOPPED, S.COMPLETE):
            self._enter(S.RESETTING, S.IDLE)
        elif name == "reset" and st == S.IDLE and self._injected.protective_stop:
            self._injected.protective_stop = False  # the cell unlocks a stop latched in Idle
        elif name == "stop" and st not in (
            S.STOPPED,
            S.STOPPING,
            S.ABORTING,
            S.ABORTED,
            S.CLEARING,
        ):
            job = self._job or self._queued
            if job is not None:
                job.end_code = ResultCode.ABORTED_BY_PLC
                self._finish(job)
            self._enter(S.STOPPING, S.STOPPED)
        else:
            return False
        return True

    def _abort(self, code: ResultCode) -> None:
        job = self._job or self._queued
        if job is not None:
            job.end_code = code
            self._finish(job)
        self._enter(S.ABORTING, S.ABORTED)

    def _finish(self, job: _Job) -> None:
        code = job.end_code if job.end_code is not None else job.result_code
        if code in COMPLETED_CODES:
            self._processed += 1
            if code != ResultCode.OK:
                self._defective += 1
        result = job.result(code, self.clock())
        self.last_result = result
        self.finished.append(result)
        self._fanout.pending.append(result)
        self._job = None
        self._queued = None

    def step(self, now_s: float | None = None) -> None:
        """Advance the fake by hand (when not ``start()``-ed) and notify listeners."""
        self._tick(self.clock() if now_s is None else now_s)
        self._notify()

    def _run(self) -> None:
        while not self._stop.wait(self.tick_s):
            self.step()

    def _tick(self, now_s: float) -> None:
        with self._lock:
            if self._next_state is not None and now_s >= self._state_until_s:
                self._arrive(self._next_state, now_s)
            elif self._state == S.EXECUTE and self._job is not None:
                self._advance(self._job, now_s)

    def _arrive(self, state: PackMLState, now_s: float) -> None:
        self._state, self._next_state = state, None
        if state == S.EXECUTE and self._job is None and self._queued is not None:
            self._job, self._queued = self._queued, None
            self._job.step_index = 1
            self._job.step_left_s = self._job.task.step_durations_s[0]
        elif state == S.COMPLETE:
            self._enter(S.RESETTING, S.IDLE)  # production cells reset automatically
        self._last_tick_s = now_s

    def _advance(self, job: _Job, now_s: float) -> None:
        dt = max(0.0, now_s - self._last_tick_s)
        self._last_tick_s = now_s
        job.step_left_s -= dt
        while job.step_left_s <= 0:
            if job.step_index >= len(job.task.step_durations_s):
                self._finish(job)
                self._enter(S.COMPLETING, S.COMPLETE)
                return
            job.step_index += 1
            job.step_left_s += job.task.step_durations_s[job.step_index - 1]

    def _notify(self) -> None:
        self._fanout.notify()


def _arm_status(job: _Job | None, injected: _Injected, now: float) -> ArmStatus:
    """A UR5e whose base joint turns at 0.5 rad/s while ``job`` runs."""
    base = 0.5 * (now - job.started_s) if job is not None else 0.0
    return ArmStatus(
        model="ur5e",
        serial_number="20235500042",
        controller="UR5e (fake)",
        q_rad=(base, -1.57, 1.57, -1.57, -1.57, 0.0),
        qd_rad_s=(0.5 if job is not None else 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        emergency_stop=injected.estop,
        protective_stop=injected.protective_stop,
        task=job.task.name if job is not None else "",
        time_s=now,
    )


def _result_text(code: ResultCode) -> str:
    return code.text


def _check_params(task: FakeTask, params: dict[str, int | float]) -> str:
    known = {p.name: p for p in task.params}
    for name, value in params.items():
        spec = known.get(name)
        if spec is None:
            names = ", ".join(known) or "none"
            return f"unknown param {name!r} for task {task.name}; known: {names}"
        if spec.type == "int" and float(value) != int(value):
            return f"param {name}={value} must be an integer"
        if not spec.min <= value <= spec.max:
            return f"param {name}={value} outside [{spec.min:g}, {spec.max:g}]"
    return ""
