"""structlog set-up: console lines or JSON lines on stderr, bound with the cell name."""

from __future__ import annotations

import logging
import sys


def configure(fmt: str, cell: str):
    """A logger bound with ``cell``; events carry job_id, step and attempt when bound."""
    import structlog

    renderer = (structlog.processors.JSONRenderer() if fmt == "json"
                else structlog.dev.ConsoleRenderer(colors=sys.stderr.isatty()))
    structlog.configure(
        processors=[structlog.processors.add_log_level, structlog.processors.TimeStamper(fmt="iso", utc=True),
                    renderer],
        wrapper_class=structlog.make_filtering_bound_logger(logging.INFO),
        logger_factory=structlog.PrintLoggerFactory(file=sys.stderr),
        cache_logger_on_first_use=False,
    )
    return structlog.get_logger().bind(cell=cell)
