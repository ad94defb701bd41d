"""OPC UA users: a YAML file of ``user: hash`` with salted scrypt hashes, and roles.

``cellrunner users add FILE NAME [--role operator|viewer] --password-stdin`` adds (or
replaces) one entry; an operator (the default) is written as its hash alone, a viewer
as a mapping with its role::

    # cellrunner OPC UA users: name -> scrypt$N$r$p$salt$hash (base64), or {hash, role}
    plc1: scrypt$16384$8$1$0mB1...$Yx3f...
    mes-dashboard: {hash: scrypt$16384$8$1$a9Qw...$Lm2p..., role: viewer}

An operator may start, hold and abort jobs; a viewer reads everything and starts, holds
or aborts nothing (SPEC section 13).

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
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, TextIO

from cellrunner.errors import InputError

SCHEME = "scrypt"
SCRYPT_N, SCRYPT_R, SCRYPT_P = 2**14, 8, 1
SALT_BYTES = 16
KEY_BYTES = 32
NAME_PATTERN = re.compile(r"^[A-Za-z0-9_.@-]{1,64}$")
HEADER = "# cellrunner OPC UA users: name -> scrypt$N$r$p$salt$hash (base64), or {hash, role}\n"

Role = Literal["operator", "viewer"]
#: the roles a user may have; the first is the default
ROLES: tuple[Role, ...] = ("operator", "viewer")


@dataclass(frozen=True)
class UserEntry:
    """One user of the users file: its salted hash and its role."""

    hash: str
    role: Role = "operator"


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
    return {name: entry.hash for name, entry in load_user_entries(path).items()}


def load_user_entries(path: Path | str) -> dict[str, UserEntry]:
    """The users of a users file with their roles; InputError if unreadable or malformed."""
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
    return {name: _entry(name, value, path) for name, value in data.items()}


def role_checker(path: Path | str) -> Callable[[str, str], Role | None]:
    """``(name, password) -> role`` of the users file at ``path``, None for an unknown user,
    a wrong password or an unreadable file; the file is read at each check (``users add``
    takes effect at once), an unknown user costs the same time as a known one."""

    def check(name: str, password: str) -> Role | None:
        try:
            entry = load_user_entries(path).get(name)
        except InputError:
            entry = None
        ok = verify_password(entry.hash if entry is not None else None, password)
        return entry.role if entry is not None and ok else None

    return check


def _entry(name: object, value: object, path: Path) -> UserEntry:
    """A users file entry: ``hash`` (an operator) or ``{hash: ..., role: ...}``."""
    role: object = ROLES[0]
    if isinstance(value, dict):
        mapping: dict[str, object] = value
        value, role = mapping.get("hash"), mapping.get("role", ROLES[0])
    if (
        not isinstance(name, str)
        or not isinstance(value, str)
        or not value.startswith(SCHEME + "$")
    ):
        raise InputError(
            f"user {name!r}: expected a '{SCHEME}$...' hash written by `cellrunner users add`",
            file=path,
        )
    if role not in ROLES:
        raise InputError(
            f"user {name!r}: role {role!r} is not one of {', '.join(ROLES)}", file=path
        )
    return UserEntry(value, role)


def add_user(path: Path | str, name: str, password: str, role: str = ROLES[0]) -> None:
    """Add or replace ``name`` with ``role`` in the users file (created 0600 if absent),
    atomically."""
    path = Path(path)
    if not NAME_PATTERN.match(name):
        raise InputError(
            f"user name {name!r} is not valid; use 1-64 of A-Z a-z 0-9 _ . @ -", file=path
        )
    if not password:
        raise InputError("empty password; give a non-empty password on stdin", file=path)
    if role not in ROLES:
        raise InputError(f"role {role!r} is not one of {', '.join(ROLES)}", file=path)
    users = load_user_entries(path) if path.exists() else {}
    users[name] = UserEntry(hash_password(password), role)
    path.parent.mkdir(parents=True, exist_ok=True)
    body = HEADER + "".join(_line(user, entry) for user, entry in sorted(users.items()))
    fd, tmp = tempfile.mkstemp(prefix=".users-", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            handle.write(body)
        os.chmod(tmp, 0o600)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _line(name: str, entry: UserEntry) -> str:
    if entry.role == ROLES[0]:
        return f"'{name}': '{entry.hash}'\n"
    return f"'{name}': {{hash: '{entry.hash}', role: {entry.role}}}\n"


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
    add.add_argument(
        "--role",
        choices=ROLES,
        default=ROLES[0],
        help="operator (starts and stops jobs) or viewer (reads only); default operator",
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
    role = getattr(args, "role", None) or ROLES[0]
    add_user(args.file, args.name, password, role)
    print(f"{args.file}: user {args.name} ({role}) written", file=sys.stderr)
    return 0
