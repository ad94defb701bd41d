"""``serve --http [HOST:]PORT``: the read-only status page and ``/metrics`` on a stdlib
HTTP server in its own thread (one short-lived thread per request).

Routes: ``/`` the page (self-contained HTML and JS that polls ``/status.json``),
``/status.json`` the snapshot, ``/metrics`` Prometheus text. Everything else is 404;
any method but GET and HEAD is 405: nothing here changes the cell.
"""

from __future__ import annotations

import ipaddress
import json
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from typing import Any

from cellrunner.errors import CellrunnerError, UsageError
from cellrunner.web.board import StatusBoard
from cellrunner.web.metrics import CONTENT_TYPE as METRICS_TYPE

DEFAULT_HOST = "127.0.0.1"


def parse_address(text: str) -> tuple[str, int]:
    """``"8080"``, ``":8080"`` or ``"HOST:8080"`` -> (host, port); loopback by default."""
    host, sep, port_text = text.rpartition(":")
    host = host.strip("[]") if sep else ""
    if not port_text.isdigit() or not 0 <= int(port_text) <= 65535:
        raise UsageError(
            f"--http {text!r}: give [HOST:]PORT with PORT 0-65535, e.g. 127.0.0.1:8080"
        )
    return host or DEFAULT_HOST, int(port_text)


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


class StatusServer:
    """Construct (no I/O), :meth:`start` (binds, raises CellrunnerError when it
    cannot), :meth:`stop`."""

    def __init__(self, board: StatusBoard, host: str = DEFAULT_HOST, port: int = 8080) -> None:
        self.board, self.host, self.port = board, host, port
        self._httpd: ThreadingHTTPServer | None = None
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        host, port = self._httpd.server_address[:2] if self._httpd else (self.host, self.port)
        name = host if isinstance(host, str) else host.decode()
        return f"http://{name}:{port}/"

    def start(self) -> None:
        handler = type("Handler", (_Handler,), {"board": self.board, "page": _page()})
        try:
            self._httpd = ThreadingHTTPServer((self.host, self.port), handler)
        except OSError as exc:
            raise CellrunnerError(
                f"cannot serve the status page on {self.host}:{self.port}: {exc}"
            ) from exc
        self._httpd.daemon_threads = True
        self._thread = threading.Thread(
            target=self._httpd.serve_forever,
            kwargs={"poll_interval": 0.2},
            name="status-http",
            daemon=True,
        )
        self._thread.start()

    def stop(self) -> None:
        if self._httpd is not None:
            self._httpd.shutdown()
            self._httpd.server_close()
            self._httpd = None
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None


def _page() -> bytes:
    return resources.files("cellrunner.web").joinpath("page.html").read_bytes()


class _Handler(BaseHTTPRequestHandler):
    board: StatusBoard
    page: bytes
    server_version = "cellrunner"

    def do_GET(self) -> None:  # http.server's name
        path = self.path.split("?", 1)[0]
        if path in ("/", "/index.html"):
            self._send(200, "text/html; charset=utf-8", self.page)
        elif path == "/status.json":
            body = json.dumps(self.board.snapshot(), separators=(",", ":")).encode()
            self._send(200, "application/json", body)
        elif path == "/metrics":
            self._send(200, METRICS_TYPE, self.board.metrics().encode())
        else:
            self._send(
                404, "text/plain; charset=utf-8", b"not found: try /, /status.json or /metrics\n"
            )

    def do_HEAD(self) -> None:
        self.do_GET()

    def _refuse(self) -> None:
        self._send(405, "text/plain; charset=utf-8", b"read-only: GET only\n", allow="GET, HEAD")

    do_POST = do_PUT = do_DELETE = do_PATCH = _refuse

    def _send(self, code: int, content_type: str, body: bytes, **headers: str) -> None:
        self.send_response(code)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        for name, value in headers.items():
            self.send_header(name.capitalize(), value)
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def log_message(self, format: str, *args: Any) -> None:  # requests are not logged
        pass
