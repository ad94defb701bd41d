"""A real Firefox driven over WebDriver BiDi (the W3C protocol Firefox speaks natively, a
websocket), as tests/web/browser.py drives Chromium over CDP.

Just enough for the status page tests: open a URL, evaluate JavaScript, take a
screenshot. A fresh profile with WebGL allowed in software and nothing that calls home.
Firefox offers no WebGL in ``--headless`` mode without a GPU, so a page that draws in 3D
runs it on a virtual X display (:func:`virtual_display`, Xvfb) where Mesa's llvmpipe
draws.
"""

from __future__ import annotations

import base64
import contextlib
import json
import shutil
import socket
import subprocess
import time
from pathlib import Path

from tests.web.websocket_browser import WebSocketBrowser

PREFS = {
    "webgl.force-enabled": True,  # no GPU: Mesa's software rasteriser
    "webgl.disabled": False,
    "app.update.enabled": False,
    "app.update.auto": False,
    "browser.shell.checkDefaultBrowser": False,
    "datareporting.policy.dataSubmissionEnabled": False,
    "datareporting.healthreport.uploadEnabled": False,
    "toolkit.telemetry.enabled": False,
    "browser.startup.homepage_override.mstone": "ignore",
    "network.captive-portal-service.enabled": False,
    "network.connectivity-service.enabled": False,
    "extensions.update.enabled": False,
    "browser.safebrowsing.malware.enabled": False,
    "browser.safebrowsing.phishing.enabled": False,
}


def firefox_path() -> str | None:
    return shutil.which("firefox-esr") or shutil.which("firefox")


@contextlib.contextmanager
def virtual_display(width: int = 1280, height: int = 1024):
    """An Xvfb display for the duration (its name, e.g. ``":12"``), stopped after."""
    import os

    read, write = os.pipe()
    proc = subprocess.Popen(
        [
            "Xvfb",
            "-displayfd",
            str(write),
            "-screen",
            "0",
            f"{width}x{height}x24",
            "-nolisten",
            "tcp",
        ],
        pass_fds=(write,),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    os.close(write)
    try:
        with os.fdopen(read) as pipe:
            number = pipe.readline().strip()  # written once the display is up
        assert number.isdigit(), f"Xvfb gave no display (exit {proc.poll()})"
        yield f":{number}"
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Firefox(WebSocketBrowser):
    """``with Firefox(url) as page: page.evaluate("document.title")``."""

    name = "firefox"

    def __init__(
        self,
        url: str,
        *,
        width: int = 1280,
        height: int = 900,
        timeout_s: float = 60.0,
        display: str | None = None,
    ):
        """``display``: an X display to run on (e.g. from :func:`virtual_display`);
        None: ``--headless``."""
        super().__init__(url, width=width, height=height, timeout_s=timeout_s)
        self.display = display
        self.context = ""

    def _open(self) -> Firefox:
        from websockets.sync.client import connect

        exe = firefox_path()
        assert exe, "firefox is not installed (scripts/system-packages installs it as root)"
        (self._profile / "user.js").write_text(
            "".join(f"user_pref({json.dumps(k)}, {json.dumps(v)});\n" for k, v in PREFS.items())
        )
        import os

        port = _free_port()
        env = {**os.environ, "DISPLAY": self.display} if self.display else None
        self._proc = subprocess.Popen(
            [
                exe,
                *(() if self.display else ("--headless",)),
                "--no-remote",
                "--profile",
                str(self._profile),
                f"--remote-debugging-port={port}",
                f"--width={self.width}",
                f"--height={self.height}",
                "about:blank",
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env=env,
        )
        deadline = time.monotonic() + self.timeout_s
        while True:
            try:
                self._ws = self._stack.enter_context(
                    connect(f"ws://127.0.0.1:{port}/session", max_size=64 * 2**20, open_timeout=5)
                )
                break
            except OSError:
                assert self._proc.poll() is None, f"firefox exited with {self._proc.returncode}"
                assert time.monotonic() < deadline, "firefox opened no WebDriver BiDi port"
                time.sleep(0.2)
        self.call("session.new", capabilities={})
        self.context = self.call("browsingContext.getTree")["contexts"][0]["context"]
        self.call(
            "browsingContext.setViewport",
            context=self.context,
            viewport={"width": self.width, "height": self.height},
        )
        self.call("browsingContext.navigate", context=self.context, url=self.url, wait="complete")
        return self

    def _before_close(self) -> None:
        self.call("session.end")

    @staticmethod
    def _error(reply: dict) -> str | None:
        if reply.get("type") != "error":
            return None
        return f"{reply.get('error')}: {reply.get('message')}"

    def evaluate(self, expression: str):
        """The value of a JavaScript expression in the page (through JSON)."""
        result = self.call(
            "script.evaluate",
            expression=f"JSON.stringify({expression})",
            target={"context": self.context},
            awaitPromise=False,
        )
        if result.get("type") != "success":
            raise RuntimeError(f"{expression}: {result.get('exceptionDetails')}")
        value = result["result"].get("value")
        return None if value is None else json.loads(value)

    def screenshot(self, path: Path, clip: dict | None = None) -> Path:
        """The viewport as PNG (``clip``: {x, y, width, height} of it only, page pixels)."""
        params: dict = {"context": self.context}
        if clip is not None:
            params["clip"] = {"type": "box", **{k: clip[k] for k in ("x", "y", "width", "height")}}
        data = self.call("browsingContext.captureScreenshot", **params)["data"]
        path.write_bytes(base64.b64decode(data))
        return path
