"""The ``cellrunner`` command: the error boundary (arguments: :mod:`cellrunner.cli.parser`).

Commands live in their own modules and are imported only when run, so ``--help`` and
``validate`` never import mujoco, ompl or asyncua.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys

from cellrunner.cli.parser import EXIT_FAILED, EXIT_INPUT, EXIT_OK, build_parser
from cellrunner.native_threads import one_thread_each

one_thread_each()
# pydantic would scan every installed distribution for plugins at the first model (~10 ms)
os.environ.setdefault("PYDANTIC_DISABLE_PLUGINS", "1")


def _skip_pydantic_plugin_loader() -> None:
    """With plugins disabled, pydantic still imports its plugin loader at the first model,
    and the loader imports importlib.metadata (~28 ms of CPU, measured) only to learn that
    there are none: stand in for it with a loader that has none."""
    if os.environ["PYDANTIC_DISABLE_PLUGINS"] not in ("1", "true", "__all__"):
        return
    if "pydantic.plugin._loader" not in sys.modules:
        import types

        loader = types.ModuleType("pydantic.plugin._loader")
        loader.get_plugins = lambda: ()  # type: ignore[attr-defined]  # a stand-in module
        sys.modules["pydantic.plugin._loader"] = loader


_skip_pydantic_plugin_loader()


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    words = sys.argv[1:] if argv is None else argv
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:
        if exc.code == EXIT_INPUT and "--json" in words:
            _json_failure(
                argparse.Namespace(json=True), [getattr(exc, "message", "bad command line")]
            )
        raise
    if not getattr(args, "command", None):
        parser.print_help(sys.stderr)
        return EXIT_INPUT
    from cellrunner.errors import CellrunnerError, InputError, InternalError, UsageError

    try:
        module = importlib.import_module(f"cellrunner.cli.cmd_{args.module}")
    except ModuleNotFoundError as exc:
        if exc.name == f"cellrunner.cli.cmd_{args.module}":
            sys.stderr.write(f"cellrunner {args.command}: not available in this build\n")
            return EXIT_FAILED
        raise
    try:
        return int(module.run(args) or 0)
    except UsageError as exc:
        sys.stderr.write(f"cellrunner {args.command}: error: {exc.message}\n")
        _json_failure(args, [f"cellrunner {args.command}: error: {exc.message}"])
        return EXIT_INPUT
    except InputError as exc:
        for diagnostic in exc.diagnostics:
            sys.stderr.write(f"{diagnostic}\n")
        _json_failure(args, [str(d) for d in exc.diagnostics])
        return EXIT_INPUT
    except InternalError as exc:  # a bug of ours, caught by its callee: reported as one
        return _internal_error(args, exc)
    except CellrunnerError as exc:
        sys.stderr.write(f"cellrunner {args.command}: error: {exc}\n")
        _json_failure(args, [f"cellrunner {args.command}: error: {exc}"])
        return exc.exit_code
    except KeyboardInterrupt:
        sys.stderr.write("interrupted\n")
        return 130
    except BrokenPipeError:
        return EXIT_OK
    except Exception as exc:  # a bug of ours: say so in one line unless debugging
        return _internal_error(args, exc)


def _internal_error(args: argparse.Namespace, exc: Exception) -> int:
    """A bug reported in one line (exit 1); with CELLRUNNER_DEBUG set, raised again for
    its traceback."""
    if os.environ.get("CELLRUNNER_DEBUG"):
        raise exc
    sys.stderr.write(
        f"cellrunner {args.command}: internal error: {type(exc).__name__}: {exc} "
        "(set CELLRUNNER_DEBUG=1 for details)\n"
    )
    return EXIT_FAILED


def _json_failure(args: argparse.Namespace, errors: list[str]) -> None:
    """``--json`` promises one JSON object on stdout, also when the input is refused before
    anything ran (SPEC section 5): ok false, the errors as printed on stderr."""
    if not getattr(args, "json", False):
        return
    from cellrunner.cli.common import emit_json

    emit_json(
        {
            "ok": False,
            "cell": None,
            "task": None,
            "params": {},
            "cycle_time_s": 0.0,
            "steps": [],
            "errors": errors,
        }
    )


def entry() -> None:
    """The ``cellrunner`` command: :func:`main`, then the exit. A command stopped by SIGTERM
    or Ctrl-C has closed its job, journal and files by the time it returns; its exit skips
    the interpreter's teardown (a second or more with MuJoCo, pinocchio and rerun loaded),
    so that the process is gone within 2 s of the signal (SPEC, cellrunner.cli.stopping)."""
    code = main()
    from cellrunner.cli.stopping import end_process, signalled

    if signalled():
        logging.shutdown()
        end_process(code)
    sys.exit(code)


if __name__ == "__main__":  # pragma: no cover
    entry()
