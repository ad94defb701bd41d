"""A small real file system for full-disk tests: a tmpfs mounted in the test's folder.

Mounting needs root, which CI has (it runs as root); elsewhere the test fails saying so,
rather than being skipped."""

from __future__ import annotations

import contextlib
import errno
import os
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest


@contextlib.contextmanager
def small_disk(folder: Path, size_kib: int = 1024) -> Iterator[Path]:
    """``folder/disk``, a tmpfs of ``size_kib`` KiB, unmounted afterwards."""
    if os.geteuid() != 0:
        pytest.fail("this full-disk test mounts a tmpfs and needs root (CI runs as root)")
    disk = folder / "disk"
    disk.mkdir()
    subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={size_kib}k,mode=0755", "tmpfs", str(disk)],
        check=True,
        capture_output=True,
    )
    try:
        yield disk
    finally:
        subprocess.run(["umount", "-l", str(disk)], check=False, capture_output=True)


def fill(disk: Path) -> Path:
    """Fill ``disk`` to the last byte with one file; returns it (delete it to free the
    space)."""
    filler = disk / "filler"
    fd = os.open(filler, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o600)
    try:
        for block in (65536, 4096, 1):
            for _ in range(1_000_000):  # bounded: a tmpfs of a few MiB fills long before
                try:
                    os.write(fd, b"\0" * block)
                except OSError as exc:
                    assert exc.errno == errno.ENOSPC, exc
                    break
    finally:
        os.close(fd)
    return filler
