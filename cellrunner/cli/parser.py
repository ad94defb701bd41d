"""The ``cellrunner`` command line: its commands and their arguments, by concern (running
jobs, serving a cell, commissioning, files). Each command names the module that runs it
(``module``: ``cellrunner.cli.cmd_<module>``), imported only when run."""

from __future__ import annotations

import argparse
import sys
from typing import Any, NoReturn

from cellrunner import __version__

EXIT_OK, EXIT_FAILED, EXIT_INPUT, EXIT_UNREACHABLE = 0, 1, 2, 3

EPILOG = """exit codes: 0 success, 1 task infeasible or job failed, 2 invalid input,
3 cannot reach the robot or a peer"""


class _UsageExit(SystemExit):
    """argparse's usage error as an exit 2 that keeps its one-line message (for --json)."""

    def __init__(self, message: str) -> None:
        super().__init__(EXIT_INPUT)
        self.message = message


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # argparse's own usage errors: exit 2, one line
        self.print_usage(sys.stderr)
        sys.stderr.write(f"{self.prog}: error: {message}\n")
        raise _UsageExit(f"{self.prog}: error: {message}")


def _depth_source(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--depth-source",
        metavar="SPEC",
        help="a watched cell on the arm: where depth images come from: twin (the virtual "
        "controller's, the default), replay:DIR, or MODULE:FACTORY (docs/perception.md)",
    )


def _params(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "-p",
        "--param",
        action="append",
        default=[],
        metavar="K=V",
        help="task parameter, repeatable (e.g. -p slot=3)",
    )


def _cell_task(p: argparse.ArgumentParser) -> None:
    p.add_argument("cell", nargs="?", help="cell file (default: the embedded example cell)")
    p.add_argument("task", nargs="?", help="task file (default: the example pick-and-place)")


Commands = Any  # argparse's subparsers action (its class is private)


def build_parser() -> argparse.ArgumentParser:
    """The ``cellrunner`` parser with every command."""
    parser = _Parser(
        prog="cellrunner",
        description="Run Universal Robots production cells from YAML.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"cellrunner {__version__}")
    parser.add_argument(
        "--log-format",
        choices=("console", "json"),
        default="console",
        help="log events as console lines or JSON lines (default console)",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    _job_commands(sub)
    _cell_commands(sub)
    _commissioning_commands(sub)
    _file_commands(sub)
    return parser


def _job_commands(sub: Commands) -> None:
    """validate, check, dry-run, run: one job, proved, rehearsed or run."""
    _validate_command(sub)
    _check_command(sub)
    _dry_run_command(sub)
    _run_command(sub)
    _replay_command(sub)


def _validate_command(sub: Commands) -> None:
    """validate: the cell's and its tasks' schema and references, nothing planned."""
    p = sub.add_parser("validate", help="schema and reference checks only")
    p.add_argument("cell")
    p.add_argument(
        "tasks",
        nargs="*",
        metavar="TASK",
        help="task files (default: every task of the cell's tasks:)",
    )
    p.set_defaults(module="validate")


def _check_command(sub: Commands) -> None:
    """check: prove one task feasible and print its plan."""
    p = sub.add_parser("check", help="pre-flight: prove a task feasible, print the plan")
    _cell_task(p)
    _params(p)
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.add_argument("--save-plan", metavar="FILE", help="write the approved motion as JSON")
    p.add_argument("--no-cache", action="store_true", help="plan afresh, ignore the plan cache")
    p.add_argument(
        "--watch",
        metavar="SNAPSHOT",
        help="plan against a saved obstacle map too (dry-run/serve --save-map wrote it)",
    )
    p.set_defaults(module="check")


def _dry_run_command(sub: Commands) -> None:
    """dry-run: rehearse one task (or a whole run of slots) on the MuJoCo twin."""
    p = sub.add_parser("dry-run", help="run the real state machine against the MuJoCo twin")
    _cell_task(p)
    _params(p)
    p.add_argument(
        "--inject",
        action="append",
        default=[],
        metavar="FAULT@STEP",
        help="grip_miss, part_slip, protective_stop, estop, robot_disconnect, "
        "plc_disconnect, intrusion (a watched cell) at a step (index, kind, or KIND#N)",
    )
    p.add_argument("--report", metavar="DIR", help="write JSON, pictures and plots here")
    _record(p)
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.add_argument(
        "--save-map",
        metavar="FILE",
        help="a watched cell: write the obstacle map as it ended (.npz, for check --watch)",
    )
    p.add_argument(
        "--slots",
        metavar="all|A..B",
        help="a whole run: the task once per value of its pattern param, in order, in one "
        "twin (parts stay where they were put); -p NAME=A..B does the same for any int param",
    )
    p.add_argument(
        "--per-period",
        action="store_true",
        help="step the twin one controller period at a time, without look-ahead "
        "(slower; the same results)",
    )
    _shift_options(p)
    p.set_defaults(module="dryrun")


def _record(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--record",
        metavar="FILE",
        help="record the job in 3D over time: FILE.rrd (Rerun) or FILE.mcap (Foxglove)",
    )


def _replay_command(sub: Commands) -> None:
    """replay: a recording in its viewer, or a journaled job's report."""
    p = sub.add_parser(
        "replay",
        help="open a recording (FILE.rrd|FILE.mcap) or a journal's job (CELL|JOURNAL JOB_ID)",
    )
    p.add_argument("source", metavar="FILE.rrd|FILE.mcap|CELL|JOURNAL")
    p.add_argument("job_id", nargs="?", metavar="JOB_ID")
    p.add_argument(
        "--out", metavar="DIR", help="where the job's report goes (default report-JOB_ID)"
    )
    p.add_argument(
        "--recordings",
        metavar="DIR",
        help="serve --record's folder: open the job's recording if kept",
    )
    p.set_defaults(module="replay")


def _shift_options(p: argparse.ArgumentParser) -> None:
    """dry-run --shift: the task back to back for a simulated shift (SPEC 13)."""
    p.add_argument(
        "--shift",
        metavar="DURATION",
        help="a whole shift in rehearsal: the task back to back for DURATION of simulated "
        "time (8h, 90m, 1h30m), pattern slots in turn; prints parts/h, availability, "
        "MTBF, MTTR, result codes, the slowest steps and each failure's replay",
    )
    p.add_argument(
        "--faults",
        metavar="FILE",
        help="--shift: YAML of fault -> probability per job, e.g. {grip_miss: 0.005}",
    )
    p.add_argument(
        "--feed-every", type=float, metavar="S", help="--shift: a part arrives every S s"
    )
    p.add_argument(
        "--seed", type=int, default=0, help="--shift: the faults' random seed (default 0)"
    )
    p.add_argument(
        "--operator-s",
        type=float,
        metavar="S",
        help="--shift: the operator's time to clear a failed job and reset (default 60)",
    )
    p.add_argument("--progress", action="store_true", help="--shift: show a progress bar")


def _run_command(sub: Commands) -> None:
    """run: one job on the arm through ur_rtde, or on the twin."""
    p = sub.add_parser("run", help="one job on the robot through ur_rtde (or on the twin)")
    p.add_argument("cell")
    p.add_argument("task")
    _params(p)
    p.add_argument("--backend", choices=("ur", "sim"))
    p.add_argument("--robot-host", metavar="H")
    p.add_argument(
        "--image-source",
        metavar="twin|MODULE:FACTORY",
        help="where align steps get pictures on the arm (default: the twin's cameras at the robot host)",
    )
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.add_argument(
        "--speed",
        type=float,
        default=1.0,
        metavar="F",
        help="commissioning: the approved motions at F x their pace (0 < F <= 1), same path",
    )
    p.add_argument(
        "--step",
        action="store_true",
        help="commissioning: show each step and wait for Enter before running it",
    )
    _depth_source(p)
    _record(p)
    p.set_defaults(module="run")


def _cell_commands(sub: Commands) -> None:
    """serve, twin: a cell in production, and the virtual controller of its twin."""
    p = sub.add_parser("serve", help="production: PLC interface up, jobs on trigger")
    p.add_argument("cell")
    p.add_argument("--backend", choices=("ur", "sim"))
    p.add_argument("--robot-host", metavar="H")
    p.add_argument(
        "--image-source",
        metavar="twin|MODULE:FACTORY",
        help="where align steps get pictures on the arm (default: the twin's cameras at the robot host)",
    )
    p.add_argument(
        "--http",
        metavar="[HOST:]PORT",
        help="serve a read-only status page and Prometheus /metrics here "
        "(host defaults to 127.0.0.1, e.g. --http 127.0.0.1:8080)",
    )
    p.add_argument(
        "--save-map",
        metavar="FILE",
        help="a watched cell: write the obstacle map when serving stops (.npz, for check --watch)",
    )
    p.add_argument(
        "--sim-fast",
        action="store_true",
        help="with --backend sim: the twin runs as fast as it can, not at the clock's pace "
        "(soak tests: days of jobs in hours)",
    )
    p.add_argument(
        "--faults",
        metavar="FILE",
        help="with --backend sim: YAML of fault -> probability per job, e.g. "
        "{protective_stop: 0.01, estop: 0.002}; the twin makes them happen (soak tests)",
    )
    p.add_argument("--seed", type=int, default=0, help="--faults: the random seed (default 0)")
    _depth_source(p)
    p.add_argument(
        "--record",
        metavar="DIR",
        help="record each job in 3D to DIR/<job id>.rrd (Rerun; --record-format mcap: Foxglove)",
    )
    p.add_argument("--record-format", choices=("rrd", "mcap"), default="rrd")
    p.add_argument(
        "--record-max-mb",
        type=float,
        default=2048.0,
        metavar="MB",
        help="the recordings folder's size cap: the oldest files go first (default 2048)",
    )
    p.set_defaults(module="serve")

    p = sub.add_parser("twin", help="a virtual UR controller backed by the MuJoCo twin")
    p.add_argument("cell")
    p.add_argument("--host", default="127.0.0.2")
    p.set_defaults(module="twin")


def _commissioning_commands(sub: Commands) -> None:
    """teach, jog, calibrate-tcp, calibrate-camera: setting a cell up at the arm."""
    p = sub.add_parser(
        "teach", help="commissioning: a frame from the arm, written into the cell file"
    )
    p.add_argument("cell")
    p.add_argument("frame")
    p.add_argument("--robot-host", metavar="H")
    p.add_argument(
        "--points",
        type=int,
        default=1,
        metavar="N",
        help="1: the TCP pose (default); 3: origin, a +X point, a point in the XY plane",
    )
    p.add_argument("--yes", action="store_true", help="write the change without asking")
    p.set_defaults(module="teach")

    p = sub.add_parser(
        "jog", help="commissioning: the arm follows keys, a gamepad, a SpaceMouse or a program"
    )
    p.add_argument("cell")
    p.add_argument("--robot-host", metavar="H")
    p.add_argument(
        "--input",
        default="keyboard",
        metavar="keyboard|gamepad|spacemouse|udp:[ADDR:]PORT",
        help="where commands come from (default keyboard, which needs a terminal)",
    )
    p.add_argument(
        "--mode",
        choices=("joint", "base", "tool"),
        default=None,
        help="where a person's input starts (default: joint for keys, base for devices)",
    )
    _depth_source(p)
    p.set_defaults(module="jog")

    p = sub.add_parser(
        "calibrate-tcp", help="commissioning: the TCP from poses about one fixed point"
    )
    p.add_argument("cell")
    p.add_argument("--robot-host", metavar="H")
    p.add_argument(
        "--poses", type=int, default=4, metavar="N", help="poses to take, at least 4 (default 4)"
    )
    p.add_argument("--yes", action="store_true", help="write the change without asking")
    p.set_defaults(module="calibrate_tcp")

    p = sub.add_parser(
        "calibrate-camera",
        help="commissioning: a camera's pose from views of its board (hand-eye), into the cell file",
    )
    p.add_argument("cell")
    p.add_argument("camera")
    p.add_argument("--robot-host", metavar="H")
    p.add_argument(
        "--views", type=int, default=12, metavar="N", help="views to take, 6 to 40 (default 12)"
    )
    p.add_argument(
        "--image-source",
        metavar="S",
        help="twin (default: the twin's rendered camera on the robot host) or MODULE:FACTORY, "
        "a camera driver (see README)",
    )
    p.add_argument("--yes", action="store_true", help="write the change without asking")
    p.set_defaults(module="calibrate_camera")


def _file_commands(sub: Commands) -> None:
    """schema, jobs, users: the files' JSON Schema, the journal, the OPC UA users file."""
    p = sub.add_parser("schema", help="JSON Schema of cell and task files")
    p.add_argument("kind", nargs="?", choices=("cell", "task"), help="only this one")
    p.add_argument(
        "--write", metavar="DIR", help="write cell.schema.json and task.schema.json here"
    )
    p.set_defaults(module="schema")

    p = sub.add_parser("jobs", help="the journal")
    p.add_argument("cell")
    p.add_argument("--last", type=int, default=20, metavar="N")
    p.add_argument("--csv", action="store_true")
    p.add_argument(
        "--all-cells",
        action="store_true",
        help="every cell's jobs in a shared journal (e.g. a postgresql:// one), with a cell column",
    )
    p.set_defaults(module="jobs")

    p = sub.add_parser("users", help="OPC UA users")
    usub = p.add_subparsers(
        dest="users_command", metavar="ACTION", parser_class=_Parser, required=True
    )
    u = usub.add_parser("add", help="add or replace a user (salted hash)")
    u.add_argument("file")
    u.add_argument("name")
    u.add_argument(
        "--password-stdin",
        action="store_true",
        help="read the password from standard input (else prompt twice)",
    )
    u.add_argument(
        "--role",
        choices=("operator", "viewer"),
        default="operator",
        help="operator (starts, holds, aborts jobs) or viewer (reads only); default operator",
    )
    p.set_defaults(module="users")
