"""structlog set-up: console lines or JSON lines on stderr, bound with the cell name."""

from __future__ import annotations

import logging
import sys
from datetime import UTC
from typing import Any


def configure(fmt: str, cell: str) -> Any:  # a structlog logger bound with the cell
    """A logger bound with ``cell``; events carry job_id, step and attempt when bound."""
    import structlog

    renderer = (
        structlog.processors.JSONRenderer()
        if fmt == "json"
        else structlog.dev.ConsoleRenderer(colors=sys.stderr.isatty())
    )
    structlog.configure(
        processors=[
            structlog.processors.add_log_level,
            structlog.processors.TimeStamper(fmt="iso", utc=True),
            renderer,
        ],
        wrapper_class=structlog.make_filtering_bound_logger(logging.INFO),
        logger_factory=structlog.PrintLoggerFactory(file=sys.stderr),
        cache_logger_on_first_use=False,
    )
    _route_stdlib_logging(fmt)
    return structlog.get_logger().bind(cell=cell)


class _JsonLines(logging.Handler):
    """Library log records (pymodbus, asyncua) as JSON lines like our own events."""

    def emit(self, record: logging.LogRecord) -> None:
        import json
        from datetime import datetime

        try:
            line = json.dumps(
                {
                    "event": record.getMessage(),
                    "logger": record.name,
                    "level": record.levelname.lower(),
                    "timestamp": datetime.fromtimestamp(record.created, UTC).isoformat(),
                }
            )
            sys.stderr.write(line + "\n")
        except Exception:  # logging must never raise
            self.handleError(record)


def _route_stdlib_logging(fmt: str) -> None:
    """Warnings and errors of the libraries through one handler: JSON lines with
    ``--log-format json`` (never a raw pymodbus line in a JSON log), plain text otherwise."""
    root = logging.getLogger()
    for old in list(root.handlers):
        if getattr(old, "_cellrunner", False):
            root.removeHandler(old)
    handler: logging.Handler = _JsonLines() if fmt == "json" else logging.StreamHandler(sys.stderr)
    handler._cellrunner = True  # type: ignore[attr-defined]  # our mark, read with getattr
    handler.setLevel(logging.WARNING)
    root.addHandler(handler)
    if root.level > logging.WARNING or root.level == logging.NOTSET:
        root.setLevel(logging.WARNING)
