"""A throwaway PostgreSQL server for the journal tests: Debian's own binaries, a fresh
cluster (initdb) in a temporary folder, listening on one loopback address and a free
port, trust authentication, stopped and removed afterwards.

PostgreSQL refuses to run as root; as root the cluster is owned by and run as the
``postgres`` system user (created by the Debian package).
"""

from __future__ import annotations

import glob
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

from tests.rig import free_port

USER = "cellrunner"


def pg_bin(name: str) -> str | None:
    """The newest installed PostgreSQL's ``name`` (pg_ctl, initdb), or None."""
    found = sorted(
        glob.glob(f"/usr/lib/postgresql/*/bin/{name}"),
        key=lambda p: int(p.split("/")[4]) if p.split("/")[4].isdigit() else 0,
    )
    return found[-1] if found else shutil.which(name)


class PgServer:
    """``with PgServer("127.0.0.142") as pg: pg.url; pg.restart()``."""

    def __init__(self, host: str, *, durable: bool = False):
        self.host = host
        self.durable = durable  # fsync as in production (benchmarks); tests skip it
        self.port = free_port(host)
        self.root = Path(tempfile.mkdtemp(prefix="cellrunner-pg-"))
        self.data = self.root / "data"
        self._as_postgres = os.geteuid() == 0

    @property
    def url(self) -> str:
        return f"postgresql://{USER}@{self.host}:{self.port}/postgres"

    def __enter__(self) -> PgServer:
        initdb = pg_bin("initdb")
        assert initdb and pg_bin("pg_ctl"), (
            "PostgreSQL server binaries not found: install Debian's "
            "postgresql package (scripts/test does, as root)"
        )
        if self._as_postgres:
            shutil.chown(self.root, "postgres", "postgres")
            os.chmod(self.root, 0o700)
        self._run(
            initdb, "-D", str(self.data), "-U", USER, "--auth=trust", "-E", "UTF8", "--no-sync"
        )
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        try:
            self.stop("immediate")
        finally:
            shutil.rmtree(self.root, ignore_errors=True)

    def start(self) -> None:
        options = f"-c listen_addresses={self.host} -p {self.port} -k {self.root}"
        if not self.durable:
            options += " -c fsync=off -c full_page_writes=off"
        self._run(
            pg_bin("pg_ctl"),
            "-D",
            str(self.data),
            "-l",
            str(self.root / "log"),
            "-w",
            "-t",
            "60",
            "-o",
            options,
            "start",
        )

    def stop(self, mode: str = "fast") -> None:
        """``fast`` ends sessions cleanly, ``immediate`` is a crash (recovery at the next start)."""
        if (self.data / "postmaster.pid").exists():
            self._run(pg_bin("pg_ctl"), "-D", str(self.data), "-m", mode, "-w", "-t", "60", "stop")

    def restart(self, mode: str = "immediate", down_s: float = 0.0) -> None:
        self.stop(mode)
        time.sleep(down_s)
        self.start()

    def sql(self, query: str) -> list[tuple]:
        import psycopg

        with psycopg.connect(self.url, autocommit=True, connect_timeout=5) as conn:
            cur = conn.execute(query)
            return cur.fetchall() if cur.description else []

    def _run(self, *argv: str) -> None:
        cmd = ["runuser", "-u", "postgres", "--", *argv] if self._as_postgres else list(argv)
        result = subprocess.run(cmd, capture_output=True, text=True, timeout=120, cwd=self.root)
        if result.returncode != 0:
            log = self.root / "log"
            tail = log.read_text()[-1500:] if log.exists() else ""
            raise RuntimeError(f"{' '.join(argv[:1])} failed: {result.stderr[-1500:]} {tail}")
