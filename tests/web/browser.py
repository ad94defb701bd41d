"""A real headless Chromium driven over the DevTools protocol (CDP, a websocket).

Just enough for the status page tests: open a URL, evaluate JavaScript in the page,
take a screenshot. The browser runs with a fresh profile and no network but loopback
(no sync, no component updates, no background requests).
"""

from __future__ import annotations

import base64
import json
import os
import shutil
import subprocess
import time
import urllib.request
from pathlib import Path

from tests.web.websocket_browser import WebSocketBrowser

FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
    "--hide-scrollbars",
    "--remote-debugging-address=127.0.0.1",
    "--remote-debugging-port=0",
)
#: WebGL with no GPU: ANGLE on SwiftShader, the software renderer Chromium ships (which
#: it no longer falls back to by itself); for pages that draw in 3D
WEBGL_FLAGS = ("--use-angle=swiftshader", "--enable-unsafe-swiftshader")


def chromium_path() -> str | None:
    return (
        shutil.which("chromium")
        or shutil.which("chromium-browser")
        or shutil.which("google-chrome")
    )


class Chromium(WebSocketBrowser):
    """``with Chromium(url) as page: page.evaluate("document.title")``."""

    name = "chromium"

    def __init__(
        self,
        url: str,
        *,
        width: int = 1280,
        height: int = 900,
        timeout_s: float = 30.0,
        flags: tuple[str, ...] = (),
    ):
        super().__init__(url, width=width, height=height, timeout_s=timeout_s)
        self.flags = flags

    def _open(self) -> Chromium:
        from websockets.sync.client import connect

        exe = chromium_path()
        assert exe, "chromium is not installed (scripts/test installs it when run as root)"
        self._proc = subprocess.Popen(
            [
                exe,
                *FLAGS,
                *self.flags,
                f"--user-data-dir={self._profile}",
                f"--window-size={self.width},{self.height}",
                self.url,
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        port = self._devtools_port()
        deadline = time.monotonic() + self.timeout_s
        while True:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=5) as res:
                pages = [t for t in json.load(res) if t.get("type") == "page"]
            if pages or time.monotonic() > deadline:
                break
            time.sleep(0.1)
        assert pages, "chromium opened no page"
        self._ws = self._stack.enter_context(
            connect(pages[0]["webSocketDebuggerUrl"], max_size=64 * 2**20, open_timeout=10)
        )
        self.call(
            "Emulation.setDeviceMetricsOverride",
            width=self.width,
            height=self.height,
            deviceScaleFactor=1,
            mobile=False,
        )
        return self

    @staticmethod
    def _error(reply: dict) -> str | None:
        return str(reply["error"]) if "error" in reply else None

    def evaluate(self, expression: str):
        """The value of a JavaScript expression in the page (JSON-serialisable)."""
        result = self.call("Runtime.evaluate", expression=expression, returnByValue=True)
        if "exceptionDetails" in result:
            raise RuntimeError(f"{expression}: {result['exceptionDetails']}")
        return result["result"].get("value")

    def screenshot(self, path: Path, clip: dict | None = None) -> Path:
        """The page as PNG (``clip``: {x, y, width, height, scale} of it only)."""
        params: dict = {"format": "png", "captureBeyondViewport": True}
        if clip is not None:
            params["clip"] = clip
        data = self.call("Page.captureScreenshot", **params)["data"]
        path.write_bytes(base64.b64decode(data))
        return path

    def _devtools_port(self) -> int:
        marker = self._profile / "DevToolsActivePort"
        deadline = time.monotonic() + self.timeout_s
        while time.monotonic() < deadline:
            if marker.exists():
                lines = marker.read_text().splitlines()
                if lines and lines[0].isdigit():
                    return int(lines[0])
            assert self._proc.poll() is None, f"chromium exited with {self._proc.returncode}"
            time.sleep(0.05)
        raise TimeoutError("chromium did not open its DevTools port")


def keep_artifact(path: Path) -> None:
    """Copy a screenshot where a person can look at it (CELLRUNNER_ARTIFACTS=DIR)."""
    if os.environ.get("CELLRUNNER_ARTIFACTS"):
        target = Path(os.environ["CELLRUNNER_ARTIFACTS"])
        target.mkdir(parents=True, exist_ok=True)
        shutil.copy(path, target / path.name)
