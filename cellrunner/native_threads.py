"""Native thread pools (OpenMP, OpenBLAS, MKL) would spin a thread per core beside our own
single-threaded planning and control loops, and OpenBLAS's threads make small matrix
products several times slower (measured: a 10-knot motion bound 1.8 ms with one thread,
9.2 ms with two). One thread each unless the user says otherwise; call before numpy is
first imported."""

from __future__ import annotations

import os

POOLS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def one_thread_each() -> None:
    """Set every pool's thread count to 1 where the environment does not set it."""
    for name in POOLS:
        os.environ.setdefault(name, "1")
