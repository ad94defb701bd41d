"""The one exception tree of cellrunner.

::

    CellrunnerError                  base; never shown with a traceback
     ├── InputError         exit 2   bad YAML, schema, references, CLI arguments;
     │    └── UsageError             carries located Diagnostics (FILE:LINE:COL)
     ├── InfeasibleError    exit 1   `check` refuses a step (reach, collision, limits)
     ├── JobFailed          exit 1   a job ended with a non-zero result code
     ├── TransitionRefused  exit 1   a PackML command or event not allowed in the state
     ├── BackendError       exit 1   a robot backend refused a command
     │    ├── ControllerMismatch     the controller is not the cell's robot
     │    ├── RemoteControlOff       the controller is in local control
     │    ├── SafetyStop             the controller stopped the arm (``safety`` says how)
     │    └── ConnectionLost         a connection to the controller dropped
     │         └── IoConnectionLost  the RTDE link for outputs (backends.ur_io)
     ├── PeerUnreachable    exit 3   robot controller or another peer cannot be reached
     │    └── InputLost              a jog input device went away (commissioning.inputs)
     ├── StepKindError      exit 1   a step kind registered twice, or one unknown by name
     ├── InternalError      exit 1   a call breaking a function's contract: a bug, never input
     ├── JournalError       exit 3   the journal cannot be written or read (execution.journal)
     ├── RenderUnavailable  exit 1   no offscreen rendering on this machine (sim.render)
     ├── DepthError         exit 1   a depth camera sent no depth image (perception.sources)
     ├── VisionUnavailable  exit 1   OpenCV (``vision`` extra) not installed (vision.board)
     ├── ImageError         exit 1   a camera sent no picture (vision.images)
     ├── CalibrationError   exit 1   no trustworthy camera pose (vision.handeye)
     ├── TcpError           exit 1   the poses give no TCP (commissioning.tcp)
     ├── TeachError         exit 1   taught points define no frame (commissioning.teach)
     ├── CellFileError      exit 2   no place for a taught pose (commissioning.cellfile)
     └── Aborted            exit 1   the operator ended a session (commissioning.session)

Inside one package, never reaching a user (each is caught where its package meets the
rest, and turned into one of the above or into a result code):

    ControlLost          backends.ur_control    the UR control process died or hung
    ArmGeometryMissing   model.arm_geometry     no collision geometry derived for an arm model
    _TooManyValues       model.source           a file past the loader's size limits (an InputError)
    Malformed            commissioning.inputs   a UDP datagram that is not a jog command
    MotionError          twin.motion            the virtual controller cannot continue a motion
    RtdeError            twin.rtde              an RTDE peer broke the protocol (the twin closes it)
    ScriptError          twin.script            a URScript program the twin cannot run
    _UsageExit           cli.parser             argparse's usage error: a SystemExit with exit 2

Third-party errors (ur_rtde, pymodbus, asyncua, OMPL, SQLite) are translated into these
where they enter the program (``raise PeerUnreachable(...) from exc``); ur_rtde's
``RuntimeError`` texts through one table in :mod:`cellrunner.backends.ur`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from cellrunner.model.body import Body
    from cellrunner.model.failure import Failure

MAX_QUOTED_CHARS = 60  # an echoed value longer than this is shown by its start and length
MAX_MESSAGE_CHARS = 1000
# a quoted word without spaces; values with spaces are bounded by MAX_MESSAGE_CHARS
_QUOTED = re.compile(
    f"'[^'\\s]{{{MAX_QUOTED_CHARS + 1},}}'|\"[^\"\\s]{{{MAX_QUOTED_CHARS + 1},}}\""
)


def shorten(message: str) -> str:
    """``message`` with every quoted value over MAX_QUOTED_CHARS cut to its start and
    length, and the whole kept under MAX_MESSAGE_CHARS, so a huge bad value in a file
    never comes back whole on the terminal."""
    message = _QUOTED.sub(
        lambda m: f"{m[0][: MAX_QUOTED_CHARS - 20]}...{m[0][0]} ({len(m[0]) - 2} characters)",
        message,
    )
    if len(message) > MAX_MESSAGE_CHARS:
        half = MAX_MESSAGE_CHARS // 2
        message = f"{message[:half]} ... {message[-half:]}"
    return " ".join(message.splitlines())


@dataclass(frozen=True)
class Diagnostic:
    """One located message about an input file; line and col are 1-based."""

    file: str
    line: int
    col: int
    message: str
    severity: str = "error"  # "error" | "warning"

    def __post_init__(self) -> None:
        object.__setattr__(self, "message", shorten(self.message))

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.col}: {self.severity}: {self.message}"


class CellrunnerError(Exception):
    """Base of every error cellrunner raises on purpose."""

    exit_code = 1


class InputError(CellrunnerError):
    """Invalid input: one or more located diagnostics, exit code 2."""

    exit_code = 2

    def __init__(self, diagnostics: list[Diagnostic] | str, file: str | Path | None = None) -> None:
        if isinstance(diagnostics, str):
            diagnostics = [Diagnostic(str(file or "<input>"), 1, 1, diagnostics)]
        self.diagnostics = list(diagnostics)
        super().__init__("\n".join(str(d) for d in self.diagnostics))


class UsageError(InputError):
    """A bad command-line value (``-p slot=12``); printed as ``cellrunner CMD: error: ...``."""

    def __init__(self, message: str) -> None:
        super().__init__([Diagnostic("<command line>", 1, 1, message)])
        self.message = message


class InfeasibleError(CellrunnerError):
    """A task step cannot be carried out safely: ``failure`` says which step, what kind of
    refusal, why, what blocked it and the fix, as data; the message is its text."""

    exit_code = 1

    def __init__(self, failure: Failure, more: tuple[Failure, ...] = ()) -> None:
        super().__init__("; ".join(f.text() for f in (failure, *more)))
        #: the first refusal; ``more``: the job's others (its on_error steps')
        self.failure, self.more = failure, more

    @property
    def blockers(self) -> tuple[Body, ...]:
        """The links and fixtures found in the way (most frequent first)."""
        return self.failure.bodies

    @property
    def step_index(self) -> int | None:
        """The step it is about (1-based), when the raiser knows it."""
        return self.failure.step_index

    @property
    def reason(self) -> str:
        """The message without the step's name in front."""
        return self.failure.summary()

    def at_step(self, index: int, label: str) -> InfeasibleError:
        """This error about step ``index`` (``label``), if it names no step yet."""
        return InfeasibleError(self.failure.at_step(index, label), self.more)


class JobFailed(CellrunnerError):
    """A job ended with a non-zero result code (SPEC section 7)."""

    exit_code = 1

    def __init__(self, message: str, result_code: int) -> None:
        self.result_code = result_code
        super().__init__(message)


class PeerUnreachable(CellrunnerError):
    """The robot controller or another peer cannot be reached, exit code 3."""

    exit_code = 3


class StepKindError(CellrunnerError):
    """A step kind's module is wrong (two of one name, no name), or a kind that no
    module defines is asked for; the message names the known kinds."""


class InternalError(CellrunnerError):
    """A call that breaks a function's documented contract (an unsealed trajectory to
    time-scale, a speed outside (0, 1]): a bug of its caller, never the user's input,
    which is checked where it enters and is an :class:`InputError`."""


class TransitionRefused(CellrunnerError):
    """A PackML command or event that is not allowed in the current state."""


class BackendError(CellrunnerError):
    """A robot backend refused a command; the engine translates it (exit 1 if it reaches
    the command line)."""


class ControllerMismatch(BackendError):
    """The controller is not the robot the cell file describes."""


class RemoteControlOff(BackendError):
    """The controller is in local control; production needs remote control."""


class SafetyStop(BackendError):
    """The controller stopped the arm; ``safety`` (a ``model.robot_state.Safety``) says how."""

    def __init__(self, message: str, safety: object) -> None:
        super().__init__(message)
        self.safety = safety


class ConnectionLost(BackendError):
    """A connection to the controller dropped; the backend's ``reconnect`` rebuilds it."""
