"""The status page's operator buttons: Hold, Resume (Unhold) and Clear, for an operator
standing at the page (``serve --http`` on a cell whose OPC UA users file names operators).

``POST /control/hold`` (``unhold``, ``clear``) with HTTP Basic credentials of an operator
of the cell's users file (``cellrunner users add``: the same users and roles as OPC UA; a
viewer may look, not press) and the header ``X-Cellrunner-Control: 1`` (a page of another
site cannot send it without a CORS preflight, which is never answered, so a link or a
form elsewhere cannot press a button). A hold from here is the cell's
:attr:`~cellrunner.model.hold_source.HoldSource.PAGE`: the log, the journal, the page and
OPC UA say an operator on the status page held it. Each press is logged with its user.

Without a users file the page stays read-only (every POST is 405).
"""

from __future__ import annotations

import base64
import binascii
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from cellrunner.model.cellport import CellPort
from cellrunner.model.hold_source import HoldSource

#: the page's buttons: the path's last part -> the PackML command
COMMANDS = {"hold": "hold", "unhold": "unhold", "clear": "clear"}
#: the header a press must carry (see the module docstring)
HEADER = "X-Cellrunner-Control"
REALM = 'Basic realm="cellrunner", charset="UTF-8"'

#: (user, password) -> the user's role ("operator", "viewer"), None: unknown or wrong
CheckUser = Callable[[str, str], str | None]


@dataclass(frozen=True)
class Answer:
    """What the page gets back: an HTTP status, a message, extra headers."""

    status: int
    message: str
    headers: tuple[tuple[str, str], ...] = ()


class PageControls:
    """Presses of the page's buttons, checked and passed to the cell."""

    def __init__(self, cell: CellPort, check_user: CheckUser, log: Any = None) -> None:
        self.cell, self.check_user, self.log = cell, check_user, log

    def press(self, button: str, authorization: str | None, marked: bool) -> Answer:
        """``button`` pressed with the request's ``Authorization`` header; ``marked``:
        it carries :data:`HEADER`."""
        command = COMMANDS.get(button)
        if command is None:
            known = ", ".join(f"/control/{b}" for b in COMMANDS)
            return Answer(404, f"no such button {button!r}; the page's buttons: {known}")
        if not marked:
            return Answer(403, f"a button press carries the header {HEADER}: 1")
        user = _credentials(authorization)
        role = self.check_user(*user) if user is not None else None
        if user is None or role is None:
            return Answer(401, "an operator's name and password", (("WWW-Authenticate", REALM),))
        if role != "operator":
            return Answer(403, f"{user[0]} is a {role}: a viewer presses no button")
        done = self.cell.command(command, HoldSource.PAGE)
        if self.log is not None:
            self.log.info("page_command", command=command, user=user[0], accepted=done)
        if not done:
            state = self.cell.status().state_name
            return Answer(409, f"{command} is not possible in state {state}")
        return Answer(200, f"{command} by {user[0]}")


def _credentials(header: str | None) -> tuple[str, str] | None:
    """(user, password) of a ``Basic`` Authorization header, None if absent or malformed."""
    if not header:
        return None
    scheme, _, value = header.partition(" ")
    if scheme.lower() != "basic":
        return None
    try:
        text = base64.b64decode(value.strip(), validate=True).decode("utf-8")
    except (binascii.Error, UnicodeDecodeError):
        return None
    user, sep, password = text.partition(":")
    return (user, password) if sep and user else None
