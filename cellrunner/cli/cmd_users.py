"""``cellrunner users add FILE NAME [--password-stdin]``: an OPC UA user, salted hash."""

from __future__ import annotations

import argparse


def run(args: argparse.Namespace) -> int:
    from cellrunner.plc.users import run_users_command

    return run_users_command(args)
