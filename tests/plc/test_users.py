"""Users file: salted scrypt hashes, constant-time checks, the `users add` entry."""

from __future__ import annotations

import argparse
import io
import time
from pathlib import Path

import pytest

from cellrunner.errors import InputError
from cellrunner.plc.opcua import HashedUserManager
from cellrunner.plc.opcua_admission import SourceBudgets
from cellrunner.plc.pki import Pki
from cellrunner.plc.users import (
    add_user,
    configure_users_parser,
    load_users,
    run_users_command,
    verify_password,
)


def test_add_user_writes_salted_hashes_only(tmp_path: Path) -> None:
    path = tmp_path / "secrets" / "users.yaml"
    add_user(path, "plc1", "pw one")
    add_user(path, "plc2", "pw one")
    add_user(path, "1234", "digits")
    users = load_users(path)
    assert set(users) == {"plc1", "plc2", "1234"}
    assert users["plc1"] != users["plc2"]  # per-user salt
    assert "pw one" not in path.read_text()
    assert path.stat().st_mode & 0o077 == 0
    assert verify_password(users["plc1"], "pw one")
    assert not verify_password(users["plc1"], "pw two")
    assert not verify_password(None, "pw one")
    assert not verify_password("scrypt$garbage", "pw one")


def test_add_user_replaces_a_password(tmp_path: Path) -> None:
    path = tmp_path / "users.yaml"
    add_user(path, "plc1", "old")
    add_user(path, "plc1", "new")
    users = load_users(path)
    assert list(users) == ["plc1"] and verify_password(users["plc1"], "new")


@pytest.mark.parametrize(
    ("name", "password", "message"),
    [
        ("bad name", "pw", "user name 'bad name' is not valid; use 1-64 of A-Z a-z 0-9 _ . @ -"),
        ("plc1", "", "empty password; give a non-empty password on stdin"),
    ],
)
def test_add_user_refuses_bad_input(tmp_path: Path, name: str, password: str, message: str) -> None:
    with pytest.raises(InputError) as err:
        add_user(tmp_path / "users.yaml", name, password)
    assert err.value.diagnostics[0].message == message


def test_missing_users_file_names_the_fix(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="create it with `cellrunner users add"):
        load_users(tmp_path / "nope.yaml")


def test_cli_entry_reads_the_password_from_stdin(tmp_path: Path) -> None:
    parser = argparse.ArgumentParser(prog="cellrunner users")
    configure_users_parser(parser)
    path = tmp_path / "users.yaml"
    args = parser.parse_args(["add", str(path), "op", "--password-stdin"])
    assert args.handler(args, io.StringIO("s3cret\n")) == 0
    assert verify_password(load_users(path)["op"], "s3cret")
    assert run_users_command is args.handler


def test_user_manager_refuses_everything_but_a_known_password(tmp_path: Path) -> None:
    path = tmp_path / "users.yaml"
    add_user(path, "plc1", "pw")
    manager = HashedUserManager(
        path, Pki(tmp_path / "pki"), allow_insecure=True, budget=SourceBudgets(burst=100, per_s=5.0)
    )
    manager.load()
    assert manager.get_user(None, "plc1", "pw").name == "plc1"
    for username, password in [
        ("plc1", "nope"),
        ("admin", "pw"),
        ("admin", ""),
        (None, None),
        ("plc1", None),
    ]:
        assert manager.get_user(None, username, password) is None
    strict = HashedUserManager(path, Pki(tmp_path / "pki"), allow_insecure=False)
    strict.load()
    assert strict.get_user(None, "plc1", "pw", certificate=b"") is None  # no secure channel
    add_user(path, "late", "pw2")  # picked up without a restart
    assert manager.get_user(None, "late", "pw2") is not None


def test_a_login_flood_is_refused_without_hashing_until_the_budget_refills(tmp_path: Path) -> None:
    path = tmp_path / "users.yaml"
    add_user(path, "plc1", "pw")
    now = [0.0]
    manager = HashedUserManager(
        path,
        Pki(tmp_path / "pki"),
        allow_insecure=True,
        budget=SourceBudgets(burst=2, per_s=4.0, clock=lambda: now[0]),
    )
    manager.load()
    assert manager.get_user(None, "plc1", "wrong") is None
    assert manager.get_user(None, "plc1", "pw") is not None
    t0 = time.perf_counter()
    assert manager.get_user(None, "plc1", "pw") is None  # the budget is spent: refused at once
    assert time.perf_counter() - t0 < 0.01  # no scrypt was run for it
    now[0] = 0.25  # one check's worth refilled
    assert manager.get_user(None, "plc1", "pw") is not None
    assert manager.get_user(None, "plc1", "pw") is None
