"""What a step behaviour hands back when it ends (:class:`Outcome`): ok, or the result
code and message of its failure; and the shape of a behaviour (:data:`StepGen`, a
generator that yields once per controller tick and returns its outcome)."""

from __future__ import annotations

from collections.abc import Generator
from dataclasses import dataclass

from cellrunner.model.codes import ResultCode


@dataclass(frozen=True)
class Outcome:
    ok: bool
    code: ResultCode = ResultCode.OK
    message: str = ""

    @staticmethod
    def failed(code: ResultCode, message: str) -> Outcome:
        return Outcome(False, code, message)


OK = Outcome(True)


StepGen = Generator[None, None, Outcome]
