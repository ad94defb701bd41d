"""The one exception tree of cellrunner.

::

    CellrunnerError                  base; never shown with a traceback
     ├── InputError         exit 2   bad YAML, schema, references, CLI arguments;
     │                               carries located Diagnostics (FILE:LINE:COL)
     ├── InfeasibleError    exit 1   `check` refuses a step (reach, collision, limits)
     ├── JobFailed          exit 1   a job ended with a non-zero result code
 ├── BackendError       exit 1   a robot backend refused a command (backends/base.py)
     └── PeerUnreachable    exit 3   robot controller or another peer cannot be reached

Third-party errors (ur_rtde, pymodbus, asyncua, OMPL) are translated into these where
they enter the program (``raise PeerUnreachable(...) from exc``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Diagnostic:
    """One located message about an input file; line and col are 1-based."""

    file: str
    line: int
    col: int
    message: str
    severity: str = "error"  # "error" | "warning"

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.col}: {self.severity}: {self.message}"


class CellrunnerError(Exception):
    """Base of every error cellrunner raises on purpose."""

    exit_code = 1


class InputError(CellrunnerError):
    """Invalid input: one or more located diagnostics, exit code 2."""

    exit_code = 2

    def __init__(self, diagnostics: list[Diagnostic] | str, file: str | Path | None = None):
        if isinstance(diagnostics, str):
            diagnostics = [Diagnostic(str(file or "<input>"), 1, 1, diagnostics)]
        self.diagnostics = list(diagnostics)
        super().__init__("\n".join(str(d) for d in self.diagnostics))


class UsageError(InputError):
    """A bad command-line value (``-p slot=12``); printed as ``cellrunner CMD: error: ...``."""

    def __init__(self, message: str):
        super().__init__([Diagnostic("<command line>", 1, 1, message)])
        self.message = message


class InfeasibleError(CellrunnerError):
    """A task step cannot be carried out safely; the message names the step, and
    ``blockers`` the links and fixtures found in the way (most frequent first)."""

    exit_code = 1

    def __init__(self, message: str, blockers: tuple[str, ...] = ()):
        super().__init__(message)
        self.blockers = tuple(blockers)


class JobFailed(CellrunnerError):
    """A job ended with a non-zero result code (SPEC section 7)."""

    exit_code = 1

    def __init__(self, message: str, result_code: int):
        self.result_code = result_code
        super().__init__(message)


class PeerUnreachable(CellrunnerError):
    """The robot controller or another peer cannot be reached, exit code 3."""

    exit_code = 3
