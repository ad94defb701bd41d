"""The operator's side of teach and calibrate-tcp: prompts answered with Enter on the
terminal (or a pipe), and the cell-file change shown as a diff before it is written."""

from __future__ import annotations

import sys
from typing import IO

from cellrunner.commissioning.cellfile import PoseEdit
from cellrunner.errors import CellrunnerError


class Aborted(CellrunnerError):
    """The operator ended the session (q, or end of input); nothing was written."""


class Operator:
    """Questions on ``out``, answers read from ``source`` one line each."""

    def __init__(self, source: IO[str] | None = None, out: IO[str] | None = None) -> None:
        self.source = source if source is not None else sys.stdin
        self.out = out if out is not None else sys.stderr

    def say(self, text: str) -> None:
        self.out.write(text + "\n")
        self.out.flush()

    def ask(self, question: str) -> str:
        """The answer to ``question`` (stripped); Aborted on ``q`` or end of input."""
        self.out.write(question + "\n")
        self.out.flush()
        line = self.source.readline()
        if not line or line.strip().lower() in ("q", "quit"):
            raise Aborted("stopped by the operator; the cell file is unchanged")
        return line.strip()


def offer(edit: PoseEdit, operator: Operator, yes: bool, what: str) -> bool:
    """Show the diff of ``edit`` on stdout; write it with ``yes`` or when the operator
    answers y. True when written."""
    sys.stdout.write(edit.diff)
    sys.stdout.flush()
    if not yes:
        try:
            answer = operator.ask(f"write {what} into {edit.path}? [y/N]")
        except Aborted:
            answer = ""
        if answer.lower() not in ("y", "yes"):
            operator.say(f"{edit.path} left unchanged (answer y, or give --yes, to write it)")
            return False
    edit.apply()
    operator.say(f"wrote {what} into {edit.path}")
    return True
