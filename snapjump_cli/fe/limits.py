"""The per-design CPU-time limit (``SolverSettings.time_limit_s``).

:func:`time_limit` sets a deadline on the CPU time of the calling thread for the block it guards
(one design: meshing, the trace, the lower state, the mesh check's re-solve, the harmonic check);
the model checks it at every evaluation (:func:`check_time`, about a microsecond against the
tenths of a millisecond of an assembly) and raises :class:`TimeLimitExceeded` once it has passed.
The time is the thread's CPU time, so a busy machine does not make a design fail, and the limit
works the same in a sweep's worker processes, in dask's worker threads and in ``curve``.
"""
from __future__ import annotations

import contextvars
import math
import time
from contextlib import contextmanager
from typing import Iterator

__all__ = ["TimeLimitExceeded", "time_limit", "check_time"]

#: (deadline in thread CPU seconds, the limit in seconds) of the innermost :func:`time_limit`.
_DEADLINE: contextvars.ContextVar[tuple[float, float] | None] = contextvars.ContextVar("snapjump_deadline",
                                                                                        default=None)


class TimeLimitExceeded(Exception):
    """The CPU-time limit of a design has passed (deliberately not a ``RuntimeError``: no solver
    stage mistakes it for a failed factorisation or Newton step)."""


@contextmanager
def time_limit(seconds: float | None) -> Iterator[None]:
    """Limit the calling thread's CPU time inside the block to ``seconds`` (``None``: no limit).

    A limit set inside another keeps the earlier of the two deadlines.
    """
    if seconds is None or not math.isfinite(seconds):
        yield
        return
    deadline = (time.thread_time() + float(seconds), float(seconds))
    outer = _DEADLINE.get()
    if outer is not None and outer[0] < deadline[0]:
        deadline = outer
    token = _DEADLINE.set(deadline)
    try:
        yield
    finally:
        _DEADLINE.reset(token)


def check_time() -> None:
    """Raise :class:`TimeLimitExceeded` if the current :func:`time_limit` has passed."""
    d = _DEADLINE.get()
    if d is not None and time.thread_time() > d[0]:
        raise TimeLimitExceeded(f"time limit of {d[1]:g} CPU-s reached (setting time_limit_s)")
