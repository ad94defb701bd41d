"""What a browser driven over one websocket needs whatever its protocol: a fresh
profile, the process stopped and the profile removed after, one command answered by its
id within a bound, an element's text. tests/web/browser.py (Chromium, CDP) and
tests/web/firefox.py (Firefox, WebDriver BiDi) add how each opens and speaks."""

from __future__ import annotations

import contextlib
import itertools
import json
import shutil
import subprocess
import tempfile
import time
from pathlib import Path


class WebSocketBrowser:
    """A browser process with a fresh profile and the websocket its driver speaks."""

    name = "browser"

    def __init__(self, url: str, *, width: int, height: int, timeout_s: float):
        self.url, self.width, self.height, self.timeout_s = url, width, height, timeout_s
        self._profile = Path(tempfile.mkdtemp(prefix=f"cellrunner-{self.name}-"))
        self._proc: subprocess.Popen | None = None
        self._ws = None
        self._stack = contextlib.ExitStack()
        self._ids = itertools.count(1)

    def __enter__(self):
        try:
            return self._open()
        except BaseException:
            self.__exit__()  # no browser left behind when it could not be opened
            raise

    def _open(self):
        raise NotImplementedError

    def _before_close(self) -> None:
        """What the protocol says before the socket closes (nothing by default)."""

    def __exit__(self, *exc) -> None:
        if self._ws is not None:
            with contextlib.suppress(Exception):
                self._before_close()
        self._stack.close()
        if self._proc is not None:
            self._proc.terminate()
            try:
                self._proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self._proc.kill()
                self._proc.wait(timeout=10)
        shutil.rmtree(self._profile, ignore_errors=True)

    @staticmethod
    def _error(reply: dict) -> str | None:
        """The protocol's error in ``reply``, or None."""
        raise NotImplementedError

    def call(self, method: str, **params) -> dict:
        """One command; its result (events on the way are skipped)."""
        msg_id = next(self._ids)
        self._ws.send(json.dumps({"id": msg_id, "method": method, "params": params}))
        deadline = time.monotonic() + self.timeout_s
        while time.monotonic() < deadline:
            reply = json.loads(self._ws.recv(timeout=max(0.1, deadline - time.monotonic())))
            if reply.get("id") == msg_id:
                error = self._error(reply)
                if error is not None:
                    raise RuntimeError(f"{method}: {error}")
                return reply["result"]
        raise TimeoutError(f"{method}: no answer within {self.timeout_s} s")

    def evaluate(self, expression: str):
        raise NotImplementedError

    def text(self, element_id: str) -> str:
        return self.evaluate(
            f"(document.getElementById({json.dumps(element_id)}) || {{}}).textContent || ''"
        )
