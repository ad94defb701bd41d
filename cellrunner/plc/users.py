"""OPC UA users: a YAML file of ``user: hash`` with salted scrypt hashes.

``cellrunner users add FILE NAME --password-stdin`` adds (or replaces) one entry::

    # cellrunner OPC UA users: name -> scrypt$N$r$p$salt$hash (base64)
    plc1: scrypt$16384$8$1$0mB1...$Yx3f...

Passwords are never stored; each user has its own 16-byte random salt; checks use
:func:`hmac.compare_digest`, and an unknown user costs the same time as a known one.
"""

from __future__ import annotations

import argparse
import base64
import hashlib
import hmac
import os
import re
import secrets
import sys
import tempfile
from pathlib import Path
from typing import TextIO

from cellrunner.errors import InputError

SCHEME = "scrypt"
SCRYPT_N, SCRYPT_R, SCRYPT_P = 2**14, 8, 1
SALT_BYTES = 16
KEY_BYTES = 32
NAME_PATTERN = re.compile(r"^[A-Za-z0-9_.@-]{1,64}$")
HEADER = "# cellrunner OPC UA users: name -> scrypt$N$r$p$salt$hash (base64)\n"


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


def hash_password(password: str, *, salt: bytes | None = None) -> str:
    """``scrypt$N$r$p$salt$hash`` for ``password`` with a fresh random salt."""
    salt = secrets.token_bytes(SALT_BYTES) if salt is None else salt
    key = hashlib.scrypt(
        password.encode("utf-8"), salt=salt, n=SCRYPT_N, r=SCRYPT_R, p=SCRYPT_P, dklen=KEY_BYTES
    )
    return f"{SCHEME}${SCRYPT_N}${SCRYPT_R}${SCRYPT_P}${_b64(salt)}${_b64(key)}"


_DUMMY_HASH = (
    f"{SCHEME}${SCRYPT_N}${SCRYPT_R}${SCRYPT_P}${_b64(bytes(SALT_BYTES))}${_b64(bytes(KEY_BYTES))}"
)


def verify_password(stored: str | None, password: str) -> bool:
    """True if ``password`` matches ``stored``; a None/garbled entry is never a match."""
    entry = stored if stored is not None else _DUMMY_HASH
    try:
        scheme, n, r, p, salt_b64, key_b64 = entry.split("$")
        if scheme != SCHEME:
            return False
        salt, expected = base64.b64decode(salt_b64), base64.b64decode(key_b64)
        key = hashlib.scrypt(
            password.encode("utf-8"),
            salt=salt,
            n=int(n),
            r=int(r),
            p=int(p),
            dklen=len(expected),
            maxmem=256 * 1024 * 1024,
        )
    except (ValueError, TypeError):
        return False
    return hmac.compare_digest(key, expected) and stored is not None


def load_users(path: Path | str) -> dict[str, str]:
    """The ``name -> hash`` entries of a users file; InputError if unreadable or malformed."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError as exc:
        raise InputError(
            f"OPC UA users file {path} not found; create it with "
            f"`cellrunner users add {path} NAME --password-stdin`",
            file=path,
        ) from exc
    except OSError as exc:
        raise InputError(
            f"cannot read OPC UA users file {path}: {exc.strerror}", file=path
        ) from exc
    from ruamel.yaml import YAML
    from ruamel.yaml.error import YAMLError

    try:
        data = YAML(typ="safe").load(text)
    except YAMLError as exc:
        raise InputError(f"users file is not valid YAML: {exc}", file=path) from exc
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise InputError("users file must be a mapping of user name -> hash", file=path)
    users: dict[str, str] = {}
    for name, value in data.items():
        if (
            not isinstance(name, str)
            or not isinstance(value, str)
            or not value.startswith(SCHEME + "$")
        ):
            raise InputError(
                f"user {name!r}: expected a '{SCHEME}$...' hash written by `cellrunner users add`",
                file=path,
            )
        users[name] = value
    return users


def add_user(path: Path | str, name: str, password: str) -> None:
    """Add or replace ``name`` in the users file (created 0600 if absent), atomically."""
    path = Path(path)
    if not NAME_PATTERN.match(name):
        raise InputError(
            f"user name {name!r} is not valid; use 1-64 of A-Z a-z 0-9 _ . @ -", file=path
        )
    if not password:
        raise InputError("empty password; give a non-empty password on stdin", file=path)
    users = load_users(path) if path.exists() else {}
    users[name] = hash_password(password)
    path.parent.mkdir(parents=True, exist_ok=True)
    body = HEADER + "".join(f"'{user}': '{value}'\n" for user, value in sorted(users.items()))
    fd, tmp = tempfile.mkstemp(prefix=".users-", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            handle.write(body)
        os.chmod(tmp, 0o600)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


# -- CLI: `cellrunner users add FILE NAME --password-stdin` ------------------------------
def configure_users_parser(parser: argparse.ArgumentParser) -> None:
    """Fill the ``users`` subcommand's parser (``users add FILE NAME --password-stdin``)."""
    sub = parser.add_subparsers(dest="users_command", required=True, metavar="{add}")
    add = sub.add_parser("add", help="add or replace an OPC UA user (salted hash)")
    add.add_argument("file", type=Path, metavar="FILE", help="users file (plc.opcua.users)")
    add.add_argument("name", metavar="NAME", help="user name")
    add.add_argument(
        "--password-stdin",
        action="store_true",
        help="read the password from the first line of stdin",
    )
    add.set_defaults(handler=run_users_command)


def read_password(stdin: TextIO, *, from_stdin: bool) -> str:
    """The password: stdin's first line (``--password-stdin``) or a hidden prompt."""
    if from_stdin:
        return stdin.readline().rstrip("\r\n")
    if not stdin.isatty():
        raise InputError("no terminal to ask for the password; use --password-stdin")
    import getpass

    first = getpass.getpass("password: ")
    if getpass.getpass("again: ") != first:
        raise InputError("the two passwords differ")
    return first


def run_users_command(args: argparse.Namespace, stdin: TextIO | None = None) -> int:
    """Run ``users add``; returns the exit code (InputError propagates: exit 2)."""
    password = read_password(stdin or sys.stdin, from_stdin=args.password_stdin)
    add_user(args.file, args.name, password)
    print(f"{args.file}: user {args.name} written", file=sys.stderr)
    return 0
