"""The one rig for tests that run cellrunner: its commands as a user runs them, on
loopback, with real sockets and free ports. Import what you need from here (never from a
test module):

- :func:`cli` runs any ``cellrunner`` command in a child process; :func:`cli_json` and
  :func:`dry_run` run one with ``--json`` and hand back its JSON (exit code checked);
  :func:`main_json` runs one in this process (faster, for many runs);
- :func:`free_port` gives a free TCP port on a loopback address (never hard-code ports:
  the suite runs in parallel, ``pytest -n 2``);
- :func:`start_twin` / :func:`twin` (``cellrunner twin``, the virtual UR controller; each
  test its own 127.0.0.x host, as UR's ports are fixed), :func:`run_ur`, :func:`fault`;
- :func:`start_serve` (``cellrunner serve``), :func:`modbus_client`, :func:`wait_bits`
  and :func:`plc_job` (a Modbus PLC running one job), :func:`opcua_job` (an OPC UA one);
- :data:`CELL` and :data:`TASK`, a small pick-and-place cell for the twin, and
  :func:`write_cell` to lay a project (cells/, tasks/) out under a folder;
- :class:`Rig`: the twin, ``serve --backend ur`` against it and a heartbeat probe, for
  reliability tests.

Example::

    from tests.rig import CELL, TASK, dry_run, write_cell

    def test_my_job(tmp_path):
        cell, task = write_cell(tmp_path, CELL, TASK)
        out = dry_run(cell, task, "-p", "slot=2")
        assert out["result_code"] == 0
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from pyModbusTCP.client import ModbusClient

from tests.conftest import ROOT

#: the environment of every child: offscreen GL that needs no display, one BLAS thread
ENV = {**os.environ, "MUJOCO_GL": "osmesa", "OMP_NUM_THREADS": "1"}
CLI = (sys.executable, "-m", "cellrunner.cli.main")
OPCUA_USER, OPCUA_PASSWORD = "line3", "s3cret pass"
OPCUA_CLIENT_URI = "urn:cellrunner:test-client"

READY, JOB_ACK, BUSY, DONE, ERROR, REJECTED = 1, 2, 4, 8, 16, 512
PROTECTIVE_STOP, ESTOP = 64, 128
JOB_REQ, RESET = 1, 2
MODBUS_HOST = "127.0.0.130"

#: a small pick-and-place cell for the twin (a UR10e, a can from pick to drop)
CELL = """
cell: dryrun-cell
robot:
  model: ur10e
  backend: sim
  mount: {xyz: [0, 0, 0.8], rpy: [0, 0, 180]}
  home: [0, -90, 90, -90, -90, 0]
  limits: {joint_speed: 110, joint_accel: 400, tcp_speed: 1.2, margin: 0.9}
tool:
  tcp: {xyz: [0, 0, 0.17]}
  payload: {mass: 1.5, cog: [0, 0, 0.06]}
  gripper: {kind: io, close: {output: jaws, value: true}, closed_sensor: jaws_closed, stroke: 0.08, close_time: 0.25}
  geometry: [{cylinder: {radius: 0.045, length: 0.1}, xyz: [0, 0, 0.05]}]
io:
  outputs: {jaws: TO0}
  inputs: {jaws_closed: TI0}
fixtures:
  - {name: bench, box: {size: [1.6, 1.2, 0.05]}, pose: {xyz: [0.5, 0, 0.775]}}
frames:
  pick: {xyz: [0.7, -0.4, 0.83], rpy: [180, 0, 45]}
  drop: {xyz: [0.7, 0.4, 0.835], rpy: [180, 0, 0]}
parts:
  - {name: can, cylinder: {radius: 0.025, length: 0.06}, mass: 0.4, at: pick}
"""

TASK = """
task: move_can
steps:
  - move: home
  - pick:
      at: pick
      approach: 0.12
      grip: {confirm: jaws_closed, force: {min: 2.5, max: 30}, timeout: 1.0}
      retry: {attempts: 2, between: [release, {retreat: 0.04}]}
  - place: {at: drop, approach: 0.12}
  - move: home
on_protective_stop: {resume: true, max: 1}
"""

#: moves only: the twin behind `cellrunner twin` has no infeed, so a second pick would
#: find no part; a fault test wants every job to be able to end OK. Two motions (1.2 s
#: and 0.6 s): out and back to home, so every job starts where the last one ended
TOUR = """
task: tour
steps:
  - move: {to: drop, offset: [0, 0, -0.15]}
  - move: home
on_protective_stop: {resume: true, max: 3}
"""


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port free on ``host`` now (the OS picks it)."""
    import socket

    with socket.socket() as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def cli(*args: str, timeout_s: float = 600, **kw: Any) -> subprocess.CompletedProcess[str]:
    """``cellrunner ARGS`` run to the end in a child process (from the repository root
    unless ``cwd=`` says otherwise; ``kw`` to :func:`subprocess.run`)."""
    kw.setdefault("env", ENV)
    kw.setdefault("cwd", ROOT)
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=timeout_s, **kw)


def cli_json(*args: str, **kw: Any) -> tuple[int, dict[str, Any]]:
    """``cellrunner ARGS --json`` in a child process: (exit code, its JSON object); no
    traceback on stderr."""
    r = cli(*args, "--json", **kw)
    assert "Traceback" not in r.stderr, r.stderr[-3000:]
    assert r.stdout, r.stderr[-3000:]
    return r.returncode, json.loads(r.stdout)


def dry_run(cell: Path | str, task: Path | str, *extra: str, **kw: Any) -> dict[str, Any]:
    """``cellrunner dry-run CELL TASK EXTRA --json`` in a child process: its JSON, after
    checking the exit code agrees with the result (0 for OK, else 1)."""
    code, out = cli_json("dry-run", str(cell), str(task), *extra, **kw)
    assert code == (0 if out["result_code"] == 0 else 1), out
    return out


def main_json(*args: str) -> tuple[int, dict[str, Any]]:
    """``cellrunner ARGS --json`` run in this process (no interpreter start-up: for tests
    that run many): (exit code, its JSON object)."""
    import contextlib
    import io

    from cellrunner.cli.main import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([*args, "--json"])
    assert "Traceback" not in err.getvalue(), err.getvalue()[-3000:]
    return code, json.loads(out.getvalue())


def json_of(*args: str) -> dict[str, Any]:
    """The JSON object of ``cellrunner ARGS --json`` run in this process (:func:`main_json`)."""
    return main_json(*args)[1]


def write_cell(
    root: Path, cell: str, task: str | None = None, *, name: str = "c"
) -> tuple[Path, Path]:
    """``root/cells/NAME.yaml`` holding ``cell`` and ``root/tasks/t.yaml`` holding ``task``
    (when given), as a project lays them out: (cell path, task path)."""
    (root / "cells").mkdir(parents=True, exist_ok=True)
    (root / "tasks").mkdir(parents=True, exist_ok=True)
    cell_path, task_path = root / "cells" / f"{name}.yaml", root / "tasks" / "t.yaml"
    cell_path.write_text(cell)
    if task is not None:
        task_path.write_text(task)
    return cell_path, task_path


def write_client_cert(directory: Path, name: str) -> tuple[Path, Path]:
    """An OPC UA client certificate (DER) and its key (PEM) in ``directory``."""
    from cryptography.hazmat.primitives import serialization
    from cryptography.hazmat.primitives.asymmetric import rsa

    from cellrunner.plc.pki import make_certificate

    key = rsa.generate_private_key(public_exponent=65537, key_size=2048)
    cert = make_certificate(key, name, OPCUA_CLIENT_URI, ["localhost"], server=False)
    cert_path, key_path = directory / f"{name}.der", directory / f"{name}.pem"
    cert_path.write_bytes(cert.public_bytes(serialization.Encoding.DER))
    key_path.write_bytes(
        key.private_bytes(
            serialization.Encoding.PEM,
            serialization.PrivateFormat.PKCS8,
            serialization.NoEncryption(),
        )
    )
    return cert_path, key_path


def start_twin(cell: Path | str, host: str) -> subprocess.Popen[str]:
    """``cellrunner twin CELL --host HOST``, returned once it listens (within 60 s)."""
    proc = subprocess.Popen(
        [*CLI, "twin", str(ROOT / cell), "--host", host],
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env=ENV,
    )
    assert proc.stderr is not None
    deadline = time.monotonic() + 60
    line = ""
    while time.monotonic() < deadline and "virtual" not in line:
        line = proc.stderr.readline()
        assert line or proc.poll() is None, f"the twin exited: {proc.stderr.read()[-3000:]}"
    assert "virtual" in line, line
    return proc


def stop(proc: subprocess.Popen[str], timeout_s: float = 30) -> None:
    """SIGTERM, then SIGKILL after ``timeout_s``."""
    proc.terminate()
    try:
        proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate(timeout=10)


@contextlib.contextmanager
def twin(cell: Path | str, host: str) -> Iterator[subprocess.Popen[str]]:
    """``cellrunner twin CELL --host HOST`` until the block ends."""
    proc = start_twin(cell, host)
    try:
        yield proc
    finally:
        stop(proc)


def fault(host: str, command: str) -> str:
    """A fault made to happen in the twin's physics, over its fault channel."""
    from cellrunner.twin.server import FaultClient

    return FaultClient(host, timeout_s=10.0).command(command)


def wait_moving(
    host: str, timeout_s: float = 30, ended: Callable[[], bool] = lambda: False
) -> bool:
    """Wait until the twin at ``host`` receives set-points that move the arm from where its
    target stood at the call (by more than 1 mrad): True; False once ``ended()`` is true
    first (the job is over)."""
    start = json.loads(fault(host, "state"))["target_q_rad"]
    deadline = time.monotonic() + timeout_s
    while True:
        target = json.loads(fault(host, "state"))["target_q_rad"]
        if max(abs(a - b) for a, b in zip(target, start, strict=True)) > 1e-3:
            return True
        if ended():
            return False
        assert time.monotonic() < deadline, f"the arm did not move within {timeout_s} s"
        time.sleep(0.02)


def fault_once_moving(host: str, command: str, after_s: float = 0.3) -> None:
    """``command`` on the twin's fault channel, from a thread, ``after_s`` after the arm
    starts moving (:func:`wait_moving`): a job that is planned, started and under way."""
    import threading

    def strike() -> None:
        wait_moving(host, 120)
        time.sleep(after_s)
        fault(host, command)

    threading.Thread(target=strike, daemon=True).start()


def run_ur(cell: Path | str, task: Path | str, host: str, *extra: str) -> dict[str, Any]:
    """``cellrunner run CELL TASK --backend ur`` against the twin at ``host``: its JSON,
    after checking the exit code agrees with the result (0 for OK, else 1)."""
    r = cli(
        "run",
        str(ROOT / cell),
        str(ROOT / task),
        "--backend",
        "ur",
        "--robot-host",
        host,
        "--json",
        *extra,
        timeout_s=400,
    )
    assert r.stdout, r.stderr[-3000:]
    out: dict[str, Any] = json.loads(r.stdout)
    assert r.returncode == (0 if out["result_code"] == 0 else 1), r.stderr[-3000:]
    return out


def start_serve(cell: Path, *args: str) -> subprocess.Popen[str]:
    """``cellrunner --log-format json serve CELL ARGS`` (default ``--backend sim``)."""
    return subprocess.Popen(
        [*CLI, "--log-format", "json", "serve", str(cell), *(args or ("--backend", "sim"))],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=ENV,
    )


def modbus_client(port: int, host: str, timeout_s: float = 60.0) -> ModbusClient:
    """A Modbus PLC connected to ``serve`` at ``host:port``, once it answers."""
    client = ModbusClient(host=host, port=port, timeout=2.0, auto_open=True)
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if client.read_holding_registers(100, 14):
            return client
        time.sleep(0.2)
    raise AssertionError("serve did not come up")


def wait_bits(client: ModbusClient, mask: int, timeout_s: float, beat: list[int]) -> list[int]:
    """The status registers once every bit of ``mask`` is set (the PLC's heartbeat, in
    ``beat[0]``, kept moving meanwhile)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        beat[0] = (beat[0] + 1) % 65536
        client.write_single_register(0, beat[0])
        regs = client.read_holding_registers(100, 14)
        if regs and regs[1] & mask == mask:
            return regs
        time.sleep(0.05)
    raise AssertionError(
        f"status bits {mask:#x} not seen within {timeout_s} s: {client.read_holding_registers(100, 14)}"
    )


def plc_job(
    client: ModbusClient, job_id: int, task: int, params: list[int], beat: list[int]
) -> list[int]:
    """One job as the PLC runs it (SPEC section 7): wait READY, write the request, raise
    JobReq, see the echo, wait DONE or ERROR (at most 120 s), drop JobReq; the registers."""
    wait_bits(client, READY, 30, beat)
    client.write_multiple_registers(2, [job_id, task, *params])
    client.write_single_register(1, JOB_REQ)
    regs = wait_bits(client, JOB_ACK, 5, beat)
    assert regs[3] == job_id  # echo
    regs = wait_bits(client, BUSY, 1, beat) if not regs[1] & (DONE | ERROR) else regs
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        regs = wait_bits(client, 0, 5, beat)
        if regs[1] & (DONE | ERROR):
            break
    client.write_single_register(1, 0)
    return regs


def add_opcua_user(users_file: Path) -> None:
    """``cellrunner users add`` of :data:`OPCUA_USER` with :data:`OPCUA_PASSWORD`."""
    r = cli(
        "users",
        "add",
        str(users_file),
        OPCUA_USER,
        "--password-stdin",
        input=OPCUA_PASSWORD + "\n",
        timeout_s=60,
    )
    assert r.returncode == 0, r.stderr


def trusted_plc_certificate(root: Path) -> tuple[Path, Path]:
    """A client certificate and key for an OPC UA PLC, put in ``root/pki/trusted``."""
    cert, key = write_client_cert(root, "plc")
    (root / "pki" / "trusted").mkdir(parents=True, exist_ok=True)
    (root / "pki" / "trusted" / "plc.der").write_bytes(cert.read_bytes())
    return cert, key


def opcua_client(url: str, cert: Path, key: Path, *extra: str) -> list[str]:
    """The command line of an OPC UA PLC in its own process (tests/plc/opcua_client.py),
    SignAndEncrypt as :data:`OPCUA_USER`; ``extra`` picks the scenario and overrides."""
    return [
        sys.executable, str(ROOT / "tests" / "plc" / "opcua_client.py"), "--url", url,
        "--cert", str(cert), "--key", str(key), "--user", OPCUA_USER,
        "--password", OPCUA_PASSWORD, *extra,
    ]  # fmt: skip


def client_result(argv: list[str], timeout_s: float = 150) -> dict[str, Any]:
    """Run a client process to the end: the last JSON object it printed ({} if none)."""
    out = subprocess.run(argv, capture_output=True, text=True, timeout=timeout_s)
    lines = [line for line in out.stdout.splitlines() if line.startswith("{")]
    return json.loads(lines[-1]) if lines else {"stderr": out.stderr[-2000:]}


def opcua_job(
    url: str, cert: Path, key: Path, task: str, *extra: str, listen_timeout_s: float = 60
) -> dict[str, Any]:
    """One StartJob over OPC UA by :func:`opcua_client`, retried until the server listens;
    the client's JSON (its job, the events, the last result)."""
    argv = opcua_client(url, cert, key, "--scenario", "run", "--task", task, "--wait", "90")
    deadline = time.monotonic() + listen_timeout_s
    while True:
        result = client_result([*argv, *extra])
        if result.get("connected") or time.monotonic() > deadline:
            break
        time.sleep(1)
    assert result.get("connected"), result
    return result


def write_project(root: Path, *, opcua: bool = False) -> tuple[Path, int, str]:
    """cells/c.yaml + tasks/t.yaml under ``root``: (cell path, Modbus port, OPC UA url)."""
    (root / "cells").mkdir(exist_ok=True)
    (root / "tasks").mkdir(exist_ok=True)
    port = free_port(MODBUS_HOST)
    text = CELL + (
        "tasks: {1: tasks/t.yaml}\nplc:\n"
        f"  modbus: {{bind: {MODBUS_HOST}, port: {port}, heartbeat_timeout: 5.0}}\n"
    )
    url = ""
    if opcua:
        url = f"opc.tcp://{MODBUS_HOST}:{free_port(MODBUS_HOST)}/cellrunner"
        text += f"  opcua:\n    endpoint: {url}\n    security: [none]\n    users: secrets/users.yaml\n    pki: pki\n"
        add_opcua_user(root / "secrets" / "users.yaml")
    (root / "cells" / "c.yaml").write_text(text)
    (root / "tasks" / "t.yaml").write_text(TOUR)
    return root / "cells" / "c.yaml", port, url


class Rig:
    """twin + serve + probe; ``with Rig(tmp_path, twin_host) as rig: ...``."""

    def __init__(self, root: Path, twin_host: str, *, opcua: bool = False):
        self.cell, self.port, self.opcua_url = write_project(root, opcua=opcua)
        self.twin_host = twin_host
        self.twin: subprocess.Popen | None = None
        self.serve: subprocess.Popen | None = None
        self.probe: subprocess.Popen | None = None
        self.watch: subprocess.Popen | None = None
        self.client: ModbusClient | None = None
        self.serve_log = root / "serve.log"
        self.beat = 0

    def __enter__(self) -> Rig:
        self.twin = start_twin(self.cell, self.twin_host)
        self._log = self.serve_log.open("w")
        self.serve = subprocess.Popen(
            [*CLI, "--log-format", "json", "serve", str(self.cell)]
            + ["--backend", "ur", "--robot-host", self.twin_host],
            cwd=ROOT,
            stdout=subprocess.DEVNULL,
            stderr=self._log,
            env=ENV,
        )
        self.client = ModbusClient(host=MODBUS_HOST, port=self.port, timeout=2.0, auto_open=True)
        deadline = time.monotonic() + 60
        while not self.client.read_holding_registers(100, 14):
            assert self.serve.poll() is None, self.log_tail()
            assert time.monotonic() < deadline, "serve did not come up"
            time.sleep(0.2)
        return self

    def __exit__(self, *exc: object) -> None:
        for helper in (self.probe, self.watch):
            if helper is not None and helper.poll() is None:
                helper.kill()
        if self.serve is not None and self.serve.poll() is None:
            self.serve.send_signal(signal.SIGTERM)
            try:
                self.serve.wait(60)
            except subprocess.TimeoutExpired:
                self.serve.kill()
        self._log.close()
        if self.twin is not None:
            stop(self.twin)

    # ------------------------------------------------------------------ probe
    def start_probe(self) -> None:
        self.probe = subprocess.Popen(
            [
                sys.executable,
                str(ROOT / "tests" / "plc" / "heartbeat_probe.py"),
                "--host",
                MODBUS_HOST,
                "--port",
                str(self.port),
            ],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        assert json.loads(self.probe.stdout.readline()) == {"started": True}

    def start_watch(self) -> None:
        """An OPC UA client (its own process) reading Cell.State every 50 ms."""
        self.watch = subprocess.Popen(
            [
                sys.executable,
                str(ROOT / "tests" / "plc" / "opcua_watch.py"),
                "--url",
                self.opcua_url,
                "--user",
                OPCUA_USER,
                "--password",
                OPCUA_PASSWORD,
            ],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        assert json.loads(self.watch.stdout.readline()) == {"started": True}

    def stop_watch(self) -> dict[str, Any]:
        out, _ = self.watch.communicate("", timeout=30)
        return json.loads(out.strip().splitlines()[-1])

    def stop_probe(self) -> dict[str, Any]:
        assert self.probe is not None
        out, _ = self.probe.communicate("", timeout=30)
        return json.loads(out.strip().splitlines()[-1])

    # ------------------------------------------------------------------ PLC
    def regs(self) -> list[int]:
        assert self.client is not None
        regs = self.client.read_holding_registers(100, 14)
        assert regs, "Modbus read failed"
        return regs

    def wait(self, predicate: Any, timeout_s: float, what: str) -> list[int]:
        deadline = time.monotonic() + timeout_s
        while True:
            assert self.serve is not None and self.serve.poll() is None, (
                f"serve died\n{self.log_tail()}"
            )
            regs = self.regs()
            if predicate(regs):
                return regs
            assert time.monotonic() < deadline, (
                f"{what} not seen within {timeout_s} s: {regs}\n{self.log_tail()}"
            )
            time.sleep(0.05)

    def trigger(self, job_id: int) -> list[int]:
        """Wait READY, request job ``job_id`` (task 1), wait for ACK+BUSY."""
        assert self.client is not None
        self.wait(lambda r: r[1] & READY, 60, "READY")
        self.client.write_multiple_registers(2, [job_id, 1])
        self.client.write_single_register(1, JOB_REQ)
        return self.wait(lambda r: r[1] & (JOB_ACK | ERROR), 5, "JOB_ACK")

    def finish(self, timeout_s: float = 90) -> list[int]:
        """Wait DONE or ERROR, then drop JOB_REQ; the result registers."""
        assert self.client is not None
        regs = self.wait(lambda r: r[1] & (DONE | ERROR), timeout_s, "DONE/ERROR")
        self.client.write_single_register(1, 0)
        return regs

    def moving(self, timeout_s: float = 30) -> bool:
        """:func:`wait_moving` on this rig's twin; False if the job ended first."""
        return wait_moving(self.twin_host, timeout_s, lambda: bool(self.regs()[1] & (DONE | ERROR)))

    def reset(self) -> None:
        """RESET edges (Clear, Reset) every 2 s until READY, once the cell no longer shows
        the e-stop; an operator presses again when the first press came before the
        controller saw the e-stop released."""
        assert self.client is not None
        self.wait(lambda r: not r[1] & ESTOP, 10, "e-stop released")
        for _ in range(15):
            self.client.write_single_register(1, 0)
            self.client.write_single_register(1, RESET)
            try:
                self.wait(lambda r: r[1] & READY, 2, "READY after RESET")
                break
            except AssertionError:
                continue
        self.wait(lambda r: r[1] & READY, 1, "READY after RESET")
        self.client.write_single_register(1, 0)

    def fault(self, command: str) -> str:
        from cellrunner.twin.server import FaultClient

        return FaultClient(self.twin_host).command(command)

    def log_tail(self, n: int = 3000) -> str:
        self._log.flush()
        return self.serve_log.read_text()[-n:]
