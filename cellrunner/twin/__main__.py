"""``python -m cellrunner.twin MODEL [--host H]``: serve a virtual UR controller."""

from __future__ import annotations

import argparse
import signal
import threading

from cellrunner.model.robots import ROBOTS


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m cellrunner.twin", description=__doc__)
    parser.add_argument("model", choices=sorted(ROBOTS))
    parser.add_argument("--host", default="127.0.0.2")
    parser.add_argument(
        "--unlock-delay", type=float, default=5.0, help="protective stop unlock delay, s"
    )
    parser.add_argument(
        "--power-off", action="store_true", help="start powered off, brakes engaged"
    )
    args = parser.parse_args(argv)

    from cellrunner.twin.server import run_twin

    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    run_twin(
        args.model,
        host=args.host,
        stop_event=stop,
        unlock_delay_s=args.unlock_delay,
        start_running=not args.power_off,
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
