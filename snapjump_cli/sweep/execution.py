"""How a sweep's designs are solved: one task per design, in-process, in a joblib process pool or
on a dask.distributed cluster, surviving the death of worker processes.

The solver kernels are compiled once in the parent before the pool starts (the caller's
``warm_up``). The loky pool caps every BLAS/OpenMP/numba thread pool to 1 per worker (joblib's
``inner_max_num_threads=1``); dask workers cap themselves (:func:`limit_threads_in_worker`).
Results arrive as they finish (``return_as="generator_unordered"``). If a worker *process* dies
(segfault, OOM kill), the designs it was running (marker files in ``<out>.parts/running/``) are
re-run one at a time in a fresh worker; one that kills its worker again is recorded as ``failed``.
Any exception raised while solving a design is caught in the worker and recorded as ``failed``,
except an interruption: a ``KeyboardInterrupt`` or ``SystemExit`` that reaches the worker inside a
compiled kernel surfaces as a ``SystemError`` caused by it (CPython chains the pending exception), and
it is re-raised as what it is, so that a stopped run records no row for the design it was solving
(a resumed run solves it again).
"""
from __future__ import annotations

import logging
import os
import signal
import socket
import sys
import threading
import time
from contextlib import ExitStack
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping

from snapjump_cli.errors import SweepError, SweepInputError
from snapjump_cli.geometry.caps import Design
from snapjump_cli.sweep.checks import JOBS_PER_CORE, jobs_error, max_jobs
from snapjump_cli.sweep.rows import fill_row
from snapjump_cli.settings import MeshSettings, SolverSettings
from snapjump_cli.files import own_files, remove_own
from snapjump_cli.sweep.storage import MARKER_NAME, now_utc

__all__ = ["SolveFn", "SCHEDULER_SCHEMES", "check_scheduler", "default_solver", "die_with_parent", "solve_task", "execute", "connect"]

log = logging.getLogger(__name__)

_CONNECT_TIMEOUT_S = 15.0


#: What a sweep calls per design: ``solve_fn(design, mesh, solver) -> metrics dict`` (with
#: ``fluid=FluidSettings`` as a keyword when the sweep's fluid is air).
SolveFn = Callable[[Design, MeshSettings, SolverSettings], Mapping[str, Any]]


def default_solver() -> tuple[SolveFn, Callable[[], Any]]:
    """The FE solver and its warm-up: :func:`snapjump_cli.fe.solve.solve_design` and ``warm_up``
    (imported here: numba and gmsh are heavy)."""
    try:
        from snapjump_cli.fe import solve
    except ImportError as e:
        log.debug("importing snapjump_cli.fe.solve failed", exc_info=True)
        raise SweepError(f"cannot import the solver snapjump_cli.fe.solve: {e}") from e
    return solve.solve_design, solve.warm_up


def limit_threads_in_worker() -> None:
    """Best effort for workers we did not spawn (dask): cap numba and BLAS pools to 1 thread."""
    numba = sys.modules.get("numba")
    if numba is not None:
        try:
            numba.set_num_threads(1)
        except Exception:  # noqa: BLE001 - threading layer not initialisable: nothing to cap
            pass
    try:
        from threadpoolctl import threadpool_limits  # optional
    except ImportError:
        return
    threadpool_limits(1)

def die_with_parent(parent_pid: int, interval_s: float = 0.5) -> None:
    """Worker initializer: end this worker process as soon as its parent, the sweep, is gone.

    A sweep killed with SIGKILL cannot stop its loky workers, which would otherwise live on until
    their idle timeout (minutes), holding the terminal and joblib's shared-memory folders. A daemon
    thread polls the parent's pid every ``interval_s`` seconds and exits the process when the
    worker has been re-parented. (``prctl(PR_SET_PDEATHSIG)`` is not used: it fires when the
    *thread* that started the worker ends, and loky may start workers from a passing thread.)
    """
    if os.getppid() != parent_pid:
        os._exit(1)
    try:  # Ctrl-C reaches every process of the terminal: the sweep (the parent) stops the workers itself
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    except (ValueError, OSError):  # pragma: no cover - not the main thread
        pass

    def watch() -> None:
        while True:
            time.sleep(interval_s)
            if os.getppid() != parent_pid:
                os._exit(1)

    threading.Thread(target=watch, name="snapjump-parent-watch", daemon=True).start()


def interruption(exc: BaseException) -> BaseException | None:
    """The ``KeyboardInterrupt`` or ``SystemExit`` behind ``exc`` (itself, or an exception in its
    ``__cause__`` / ``__context__`` chain), or ``None`` if ``exc`` is a failure of its own."""
    seen: set[int] = set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        if isinstance(e, (KeyboardInterrupt, SystemExit)):
            return e
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    return None


def solve_task(task: dict[str, Any], solve_fn: SolveFn, marker_dir: str | None) -> dict[str, Any]:
    """Worker: solve one design and return its row (never raises for a design's failure)."""
    t0 = time.perf_counter()
    row = dict(task["row"])
    marker = None
    if marker_dir is not None:
        try:  # a new file, never through a link (O_EXCL, O_NOFOLLOW): nothing else is ever written
            marker = Path(marker_dir) / row["key"]
            fd = os.open(marker, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o666)
            try:
                os.write(fd, f"{os.getpid()}\n".encode())
            finally:
                os.close(fd)
        except OSError:
            marker = None
    try:
        if task.get("limit_threads"):
            limit_threads_in_worker()
        if task.get("fluid") is not None:  # air (water: the solver's default)
            result = solve_fn(task["design"], task["mesh"], task["solver"], fluid=task["fluid"])
        else:
            result = solve_fn(task["design"], task["mesh"], task["solver"])
        fill_row(row, result)
    except Exception as e:  # noqa: BLE001 - any failure of one design is recorded, never raised
        stop = interruption(e)
        if stop is not None:  # the run is being stopped: not this design's failure
            raise stop from None
        msg = str(e).strip().replace("\n", " | ")
        row.update(status="failed", error=f"{type(e).__name__}: {msg}"[:4000])
    row.update(t_total_s=time.perf_counter() - t0, host=socket.gethostname(), pid=os.getpid(), finished_utc=now_utc())
    if marker is not None:
        remove_own(marker)
    return row

def _parallel_rows(tasks: list[dict[str, Any]], solve_fn: SolveFn, n_jobs: int, backend: str,
                   marker_dir: str | None) -> Iterator[dict[str, Any]]:
    from joblib import Parallel, delayed, parallel_config

    kwargs: dict[str, Any] = {}
    if backend == "loky":
        kwargs.update(inner_max_num_threads=1, initializer=die_with_parent, initargs=(os.getpid(),))
    with parallel_config(backend=backend, **kwargs) if backend == "loky" else ExitStack():
        par = Parallel(n_jobs=n_jobs, return_as="generator_unordered", pre_dispatch="2*n_jobs")
        yield from par(delayed(solve_task)(t, solve_fn, marker_dir) for t in tasks)


def execute(tasks: list[dict[str, Any]], solve_fn: SolveFn, n_jobs: int, backend: str,
             marker_dir: Path | None) -> Iterator[dict[str, Any]]:
    """Yield one row per task, surviving the death of worker processes."""
    if n_jobs == 1 and backend == "loky":  # sequential, in-process
        for t in tasks:
            yield solve_task(t, solve_fn, None)
        return
    pending = {t["row"]["key"]: t for t in tasks}
    md = str(marker_dir) if marker_dir is not None else None
    while pending:
        try:
            for row in _parallel_rows(list(pending.values()), solve_fn, n_jobs, backend, md):
                if pending.pop(row["key"], None) is not None:
                    yield row
            return
        except Exception as exc:  # noqa: BLE001 - the pool broke (a worker died), not a design
            suspects = [p.name for p in own_files(marker_dir, MARKER_NAME)] if marker_dir is not None else []
            for p in suspects:
                remove_own(marker_dir / p)
            suspects = [k for k in suspects if k in pending]
            log.warning("the worker pool broke (%s: %s); re-running the %d design(s) it was solving one by one",
                        type(exc).__name__, exc, len(suspects))
            if not suspects:
                raise SweepError(f"the worker pool broke and no running design could be identified: "
                                 f"{type(exc).__name__}: {exc}") from exc
            for key in suspects:
                task = pending.pop(key)
                try:
                    (row,) = list(_parallel_rows([task], solve_fn, 2, backend, md))
                except Exception as exc2:  # noqa: BLE001 - this design kills its worker
                    if marker_dir is not None:
                        remove_own(marker_dir / key)
                    row = dict(task["row"])
                    row.update(status="failed", finished_utc=now_utc(),
                               error=f"worker process died while solving this design ({type(exc2).__name__}: {exc2})"[:4000])
                yield row

#: The address schemes of dask.distributed's communications (``tcp://host:port``; no scheme = tcp).
SCHEDULER_SCHEMES: tuple[str, ...] = ("tcp", "tls", "inproc", "ucx", "ws", "wss")


def check_scheduler(address: str) -> str:
    """``address`` if it has the form of a dask scheduler address (``[SCHEME://]HOST[:PORT]``,
    :data:`SCHEDULER_SCHEMES`), checked before anything is started or written.

    Raises
    ------
    SweepInputError
        One line naming the address and what is expected.
    """
    expected = f"expected SCHEME://HOST:PORT with SCHEME one of {', '.join(SCHEDULER_SCHEMES)} (e.g. tcp://10.0.0.5:8786)"
    if not isinstance(address, str) or not address.strip() or any(c.isspace() for c in address):
        raise SweepInputError(f"--scheduler: {address!r}: {expected}")
    scheme, sep, rest = address.partition("://")
    if sep and scheme.lower() not in SCHEDULER_SCHEMES:
        raise SweepInputError(f"--scheduler: {address!r}: the scheme {scheme!r} is not one dask speaks; {expected}")
    if sep and not rest:
        raise SweepInputError(f"--scheduler: {address!r}: no host; {expected}")
    return address


def connect(address: str) -> Any:
    """A dask.distributed client for ``address`` (dask imported here only)."""
    check_scheduler(address)
    try:
        from dask.distributed import Client
    except ImportError as e:  # pragma: no cover - depends on the install
        raise SweepError("--scheduler needs dask[distributed] (pip install 'snapjump[dask]')") from e
    try:
        return Client(address, timeout=_CONNECT_TIMEOUT_S, set_as_default=False)
    except (KeyboardInterrupt, SystemExit):
        raise
    except Exception as e:  # noqa: BLE001 - whatever dask raises for an address it cannot reach: one line
        why = " ".join(str(e).split())[:300] or type(e).__name__
        raise SweepInputError(f"--scheduler: cannot connect to the dask scheduler at {address!r} ({why}); check "
                              f"that it runs and the address") from None
