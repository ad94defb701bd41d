"""Running a cellrunner command in-process with ``--json`` and reading its answer."""

from __future__ import annotations

import contextlib
import io
import json
from typing import Any

from cellrunner.cli.main import main


def cli(*argv: str) -> dict[str, Any]:
    """The JSON object ``cellrunner ARGV --json`` prints (stderr swallowed)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        main([*argv, "--json"])
    result: dict[str, Any] = json.loads(out.getvalue())
    return result
