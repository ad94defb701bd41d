"""``serve --http [HOST:]PORT``: the read-only status page and ``/metrics`` on a stdlib
HTTP server in its own thread (one short-lived thread per request).

Routes: ``/`` the page (self-contained HTML and JS that polls ``/status.json``),
``/status.json`` the snapshot, ``/metrics`` Prometheus text. With a
:class:`~cellrunner.web.live.LiveView`, the live 3D view's: ``/live/scene.json``,
``/live/state.json``, ``/live/job.json``, ``/live/stream`` (server-sent events, one
state per sample, at most :data:`MAX_STREAMS` at once) and the three.js modules under
``/static/three/`` (vendored, scripts/vendor-three). Everything else is 404. With
:class:`~cellrunner.web.controls.PageControls` (a users file names the operators) the
page's buttons ``POST /control/hold``, ``/control/unhold``, ``/control/clear``; any other
POST, and any method but GET, HEAD and those, is 405: nothing else changes the cell.
"""

from __future__ import annotations

import ipaddress
import json
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from typing import TYPE_CHECKING, Any

from cellrunner.errors import CellrunnerError, UsageError
from cellrunner.web.board import StatusBoard
from cellrunner.web.controls import HEADER as CONTROL_HEADER
from cellrunner.web.metrics import CONTENT_TYPE as METRICS_TYPE

if TYPE_CHECKING:
    from cellrunner.web.controls import PageControls
    from cellrunner.web.live import LiveView

DEFAULT_HOST = "127.0.0.1"
#: live 3D streams served at once (each is one thread); more pages get 503 and retry
MAX_STREAMS = 16
#: a stream's client that takes no data for this long is dropped (s)
STREAM_WRITE_TIMEOUT_S = 5.0
_STATIC_TYPES = {".js": "text/javascript; charset=utf-8", "": "text/plain; charset=utf-8"}


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

    def __init__(
        self,
        board: StatusBoard,
        host: str = DEFAULT_HOST,
        port: int = 8080,
        live: LiveView | None = None,
        controls: PageControls | None = None,
    ) -> None:
        self.board, self.host, self.port, self.live = board, host, port, live
        self.controls = controls
        self._stopping = threading.Event()
        self._httpd: ThreadingHTTPServer | None = None
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        host, port = self._httpd.server_address[:2] if self._httpd else (self.host, self.port)
        name = host if isinstance(host, str) else host.decode()
        return f"http://{name}:{port}/"

    def start(self) -> None:
        self._stopping.clear()
        handler = type(
            "Handler",
            (_Handler,),
            {
                "board": self.board,
                "page": _page(),
                "live": self.live,
                "controls": self.controls,
                "static": _static() if self.live is not None else {},
                "stopping": self._stopping,
                "streams": threading.BoundedSemaphore(MAX_STREAMS),
            },
        )
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
        self._stopping.set()  # the live streams end within one sample period
        if self._httpd is not None:
            self._httpd.shutdown()
            self._httpd.server_close()
            self._httpd = None
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None


def _page() -> bytes:
    return resources.files("cellrunner.web").joinpath("page.html").read_bytes()


def _static() -> dict[str, tuple[str, bytes]]:
    """``/static/three/NAME`` -> (content type, bytes) of the vendored three.js files."""
    folder = resources.files("cellrunner.web").joinpath("static", "three")
    out = {}
    for item in folder.iterdir():
        suffix = "." + item.name.rsplit(".", 1)[1] if "." in item.name else ""
        if item.is_file() and suffix in _STATIC_TYPES:
            out[f"/static/three/{item.name}"] = (_STATIC_TYPES[suffix], item.read_bytes())
    return out


class _Handler(BaseHTTPRequestHandler):
    board: StatusBoard
    page: bytes
    live: LiveView | None
    controls: PageControls | None
    static: dict[str, tuple[str, bytes]]
    stopping: threading.Event
    streams: threading.BoundedSemaphore
    server_version = "cellrunner"

    def do_GET(self) -> None:  # http.server's name
        path = self.path.split("?", 1)[0]
        if path in ("/", "/index.html"):
            self._send(200, "text/html; charset=utf-8", self.page)
        elif path == "/status.json":
            snapshot = {**self.board.snapshot(), "controls": self.controls is not None}
            body = json.dumps(snapshot, separators=(",", ":")).encode()
            self._send(200, "application/json", body)
        elif path == "/metrics":
            self._send(200, METRICS_TYPE, self.board.metrics().encode())
        elif path.startswith("/live/") and self.live is not None:
            self._live(path, self.live)
        elif path in self.static:
            content_type, body = self.static[path]
            self._send(200, content_type, body, cache="public, max-age=86400")
        else:
            self._send(
                404, "text/plain; charset=utf-8", b"not found: try /, /status.json or /metrics\n"
            )

    def do_HEAD(self) -> None:
        self.do_GET()

    def _refuse(self) -> None:
        self._send(405, "text/plain; charset=utf-8", b"read-only: GET only\n", allow="GET, HEAD")

    do_PUT = do_DELETE = do_PATCH = _refuse

    def do_POST(self) -> None:  # http.server's name
        """A button of the page (see :mod:`cellrunner.web.controls`); else read-only."""
        path = self.path.split("?", 1)[0]
        if self.controls is None or not path.startswith("/control/"):
            return self._refuse()
        length = int(self.headers.get("Content-Length") or 0)
        if 0 < length <= 4096:
            self.rfile.read(length)  # a body is ignored
        answer = self.controls.press(
            path.removeprefix("/control/"),
            self.headers.get("Authorization"),
            self.headers.get(CONTROL_HEADER) == "1",
        )
        body = json.dumps({"ok": answer.status == 200, "message": answer.message}).encode()
        self._send(answer.status, "application/json", body, **dict(answer.headers))

    def _live(self, path: str, live: LiveView) -> None:
        if path == "/live/scene.json":
            self._send(200, "application/json", live.scene)
        elif path == "/live/state.json":
            self._send(200, "application/json", live.state()[1])
        elif path == "/live/job.json":
            self._send(200, "application/json", live.job())
        elif path == "/live/stream":
            self._stream(live)
        else:
            self._send(404, "text/plain; charset=utf-8", b"not found: no such live resource\n")

    def _stream(self, live: LiveView) -> None:
        """Server-sent events: each new sample's state, until the page leaves or the
        server stops; a page over :data:`MAX_STREAMS` gets 503 (its EventSource retries)."""
        if not self.streams.acquire(blocking=False):
            self._send(503, "text/plain; charset=utf-8", b"too many live views open\n")
            return
        try:
            self.send_response(200)
            self.send_header("Content-Type", "text/event-stream")
            self.send_header("Cache-Control", "no-store")
            self.end_headers()
            if self.command == "HEAD":
                return
            self.connection.settimeout(STREAM_WRITE_TIMEOUT_S)
            self.wfile.write(b"retry: 1000\n\n")
            last = -1
            while not self.stopping.is_set():
                seq, body = live.state()
                if seq != last:
                    self.wfile.write(b"data: " + body + b"\n\n")
                    self.wfile.flush()
                    last = seq
                self.stopping.wait(0.5 / live.rate_hz)
        except OSError:  # the page went away (a broken pipe, a reset, a write timeout)
            pass
        finally:
            self.streams.release()

    def _send(
        self, code: int, content_type: str, body: bytes, cache: str = "no-store", **headers: str
    ) -> None:
        self.send_response(code)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", cache)
        for name, value in headers.items():
            self.send_header(name.capitalize(), value)
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def log_message(self, format: str, *args: Any) -> None:  # requests are not logged
        pass
