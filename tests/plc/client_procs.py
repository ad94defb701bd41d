"""Client processes of the PLC tests: run them in parallel, each printing one JSON object."""

from __future__ import annotations

import json
import subprocess
from typing import Any

from tests.plc.conftest import child_env


def run_clients(argvs: list[list[str]], timeout_s: float = 60) -> list[dict[str, Any]]:
    """Run client processes in parallel; each prints one JSON object."""
    procs = [
        subprocess.Popen(
            a, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=child_env()
        )
        for a in argvs
    ]
    results = []
    for proc in procs:
        try:
            out, err = proc.communicate(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            out, err = proc.communicate()
        lines = [line for line in out.splitlines() if line.startswith("{")]
        results.append(
            json.loads(lines[-1]) if lines else {"connected": False, "error": err[-2000:]}
        )
    return results
