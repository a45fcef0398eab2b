"""Solve a grid (or a list) of designs in parallel into a chunked, resumable parquet result.

This module orchestrates; :mod:`snapjump_cli.sweep.storage` keeps the rows (keys, part files, lock,
consolidation) and :mod:`snapjump_cli.sweep.execution` solves them (in-process, joblib, dask).

Flow of :func:`run_sweep`
-------------------------
1. The output is locked (:class:`~snapjump_cli.sweep.storage.OutputLock`): a second sweep into the same
   output is refused, naming the holder.
2. Every design gets its stable key (:func:`~snapjump_cli.sweep.storage.design_key`). Keys already in
   ``<out>`` or ``<out>.parts/`` are skipped (resume); ``retry_failed=True`` solves ``failed`` ones
   again. Rows in the file that this run would never produce (another grid, mesh, solver or
   material) make the run stop before it starts, unless ``append=True``.
3. Designs that raise :class:`~snapjump_cli.geometry.caps.InvalidDesign` on construction are recorded as
   ``invalid_geometry`` in the parent and never meshed.
4. The kernels are compiled once in the parent (``warm_up``), then the designs are solved by
   :func:`snapjump_cli.sweep.execution.execute`; every finished row is validated
   (:func:`snapjump_cli.sweep.rows.fill_row`) and buffered into atomic part files.
5. At the end the parts (and a previous ``<out>``) are consolidated into ``<out>`` (atomically,
   deduplicated by key, in grid order) and the lock is released.

Every row carries its own provenance: code version and commit, mesh and solver settings, host,
pid and finish time.
"""
from __future__ import annotations

import logging
import math
import os
import sys
import time
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from snapjump_cli.errors import SweepError, SweepInputError
from snapjump_cli.files import check_writable, follow_links, own_folder, remove_own_folder
from snapjump_cli.geometry.caps import Design, InvalidDesign, centre_offset, outer_radius
from snapjump_cli.sweep import results as res
from snapjump_cli.sweep.config import MAX_DESIGNS, DesignPoint, SweepConfig
from snapjump_cli.sweep.checks import jobs_error
from snapjump_cli.sweep.execution import SolveFn, check_scheduler, connect, default_solver, execute
from snapjump_cli.sweep.rows import settings_json
from snapjump_cli.settings import MeshSettings, SolverSettings
from snapjump_cli.sweep.storage import (
    KEY_VERSION,
    MARKER_NAME,
    OutputLock,
    PartWriter,
    check_compatible,
    consolidate,
    design_key,
    done_keys,
    now_utc,
    part_files,
    parts_dir,
)

__all__ = [
    "KEY_VERSION",
    "MAX_DESIGNS",
    "SweepError",
    "SweepInputError",
    "SweepSummary",
    "design_key",
    "parts_dir",
    "done_keys",
    "consolidate",
    "estimate_seconds",
    "make_progress",
    "run_sweep",
]

log = logging.getLogger(__name__)

# The sweep's time estimate. The figures below are reference measurements of the development
# machine (an idle 2-core AMD EPYC at 2.45 GHz; docs/performance.md, "The sweep's time estimate"),
# not of the machine a sweep runs on: the estimate printed before a sweep scales them with the
# config's mesh and solver settings and with the load measured at run time (load_factor), and says
# it is rough; the progress line then reports the rate measured during the run.

#: CPU seconds per solved design on the paper grid's mesh (order 2, nt 2, aspect 3) without the
#: harmonic check: ``make run`` without the check, 800 CPU-s for 4079 designs (the mesh re-checks
#: included).
REF_CPU_S_PER_DESIGN = 0.196
#: The harmonic check (``solver.harmonics``, n <= 4) multiplies a design's CPU by this: 1057
#: against 800 CPU-s over the same grid.
REF_CHECK_FACTOR = 1.32
#: With ``solver.follow``: per followed harmonic, the share of the paper grid's valid designs whose
#: branch is followed (2128 and 789 of 4079) and the mean seconds of one followed design of that
#: class, both from the grid's own followed run (``make run-followed``, one run of the whole grid,
#: two workers on the two cores: wall ~ CPU; ``python -m bench.followed_grid_time
#: results/paper_grid_followed.parquet``, docs/performance.md), each at most the solver's
#: ``time_limit_s``.
REF_FOLLOW = {1: (2128 / 4079, 1.45), 2: (789 / 4079, 10.47)}
#: Seconds of a sweep that do not depend on the number of designs: the imports and the kernels
#: loaded in the parent, the workers started, each worker's first solve (``configs/smoke.yaml``:
#: 2 designs of ~0.07 CPU-s each on 2 workers, 3.8 CPU-s for the whole command).
REF_STARTUP_S = 4.0


def mesh_scale(mesh: MeshSettings) -> float:
    """A design's solve cost on ``mesh`` relative to the paper grid's mesh (order 2, nt 2, aspect
    3): proportional to the number of elements (``nt^2 / aspect``), a third for bilinear elements
    (a stated factor, not a measurement per design)."""
    return (mesh.nt / 2) ** 2 * (3.0 / mesh.aspect) * (1.0 if mesh.order == 2 else 1.0 / 3.0)


@dataclass
class SweepSummary:
    """What a sweep did.

    Attributes
    ----------
    output : Path
        The consolidated result file.
    n_designs : int
        Number of designs of the config.
    n_resumed : int
        Designs skipped because a previous run had recorded them.
    n_solved : int
        Designs sent to the solver in this run.
    counts : dict
        Rows per status over the whole grid (after this run).
    wall_s : float
        Wall-clock time of this run.
    """

    output: Path
    n_designs: int
    n_resumed: int = 0
    n_solved: int = 0
    counts: dict[str, int] = field(default_factory=dict)
    wall_s: float = 0.0


#: :func:`load_factor` trusts a process this young only (seconds since it started)
LOAD_WINDOW_S = 120.0


def load_factor() -> float:
    """How much slower than its CPU time this process has run since it started (its wall time over
    its CPU time, from ``/proc``), between 1 and 10; 1 where that cannot be read, the process has
    used under 0.2 CPU-s, or it started more than :data:`LOAD_WINDOW_S` ago (a notebook or a
    long-lived process has waited, not computed). Measured at run time at the start of a
    ``snapjump sweep``, it says what share of the cores the other jobs on the machine leave (the
    command's imports are CPU-bound)."""
    try:
        with open("/proc/self/stat") as f:
            start_ticks = float(f.read().rsplit(")", 1)[1].split()[19])
        with open("/proc/uptime") as f:
            uptime = float(f.read().split()[0])
        wall = uptime - start_ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError, AttributeError):
        return 1.0
    cpu = time.process_time()
    if cpu < 0.2 or wall <= 0.0 or wall > LOAD_WINDOW_S:
        return 1.0
    return min(10.0, max(1.0, wall / cpu))


def estimate_seconds(n_solve: int, mesh: MeshSettings, n_workers: int, solver: SolverSettings | None = None,
                     slowdown: float = 1.0) -> float:
    """A rough wall-time estimate of solving ``n_solve`` designs on ``n_workers`` processes.

    Derived from the reference figures of the development machine (:data:`REF_CPU_S_PER_DESIGN`,
    :data:`REF_CHECK_FACTOR`, :data:`REF_FOLLOW`, :data:`REF_STARTUP_S`), scaled by
    :func:`mesh_scale` and the ``solver`` settings: the harmonic check, and with followed branches
    each class's share of the designs at its mean cost, capped at ``solver.time_limit_s``. The
    designs share the workers evenly; the start-up is added once (none when nothing is solved).
    The whole is multiplied by ``slowdown`` (:func:`load_factor`: the load of other jobs).
    """
    if n_solve <= 0:
        return 0.0
    scale = mesh_scale(mesh)
    per = REF_CPU_S_PER_DESIGN * scale
    if solver is not None and solver.harmonics > 0:
        per *= REF_CHECK_FACTOR
        if solver.follow:
            limit = float(solver.time_limit_s) if solver.time_limit_s else math.inf
            per += sum(share * min(cpu * scale, limit) for share, cpu in REF_FOLLOW.values())
    workers = max(1, min(n_workers, n_solve))
    return (REF_STARTUP_S + n_solve * per / workers) * max(1.0, slowdown)


def _fmt_duration(s: float) -> str:
    if s < 90:
        return f"{s:.0f} s"
    if s < 5400:
        return f"{s / 60:.0f} min"
    return f"{s / 3600:.1f} h"


def _base_row(point: DesignPoint, key: str, mesh: MeshSettings, stamp: dict[str, Any]) -> dict[str, Any]:
    row: dict[str, Any] = {"key": key, "index": point.index, "status": None, "error": ""}
    row.update(point.design_kwargs())
    row.update(mesh_order=mesh.order, mesh_nt=mesh.nt, mesh_aspect=float(mesh.aspect))
    row.update(stamp)
    try:
        args = (point.eta_i, math.radians(point.theta_i_deg), point.eta_o, math.radians(point.theta_o_deg), point.R_i)
        row["R_o"] = outer_radius(*args)
        row["Delta"] = centre_offset(*args)
    except (InvalidDesign, ValueError, ZeroDivisionError):
        row["R_o"] = row["Delta"] = None
    return row


class _LineProgress:
    """Progress for a log file (stderr not a terminal): one plain line every ``every_s`` seconds."""

    def __init__(self, total: int, initial: int, every_s: float = 30.0, desc: str = "sweep",
                 unit: str = "designs") -> None:
        self.total, self.n, self.every_s, self.desc, self.unit = total, initial, every_s, desc, unit
        self.t0 = self.last = time.monotonic()
        self.n0 = initial
        self.postfix: dict[str, int] = {}

    def update(self, k: int) -> None:
        self.n += k
        now = time.monotonic()
        if now - self.last >= self.every_s or self.n == self.total:
            self.last = now
            rate = (self.n - self.n0) / max(now - self.t0, 1e-9)
            eta = (self.total - self.n) / rate if rate > 0 else float("nan")
            counts = ", ".join(f"{k}={v}" for k, v in self.postfix.items())
            sys.stderr.write(f"{self.desc}: {self.n}/{self.total} {self.unit} ({100 * self.n / max(self.total, 1):.0f} %), "
                             f"{rate:.2f} {self.unit}/s" + (f", ~{_fmt_duration(eta)} left" if math.isfinite(eta) else "")
                             + (f"; {counts}" if counts else "") + "\n")
            sys.stderr.flush()

    def set_postfix(self, d: dict[str, int], refresh: bool = False) -> None:
        self.postfix = d

    def close(self) -> None:
        pass


def make_progress(total: int, initial: int, stack: ExitStack, desc: str = "sweep", unit: str = "design") -> Any:
    """Progress on stderr: a tqdm bar on a terminal, else a plain line every 30 s (log files get no
    carriage returns). The caller closes it; ``stack`` holds the log redirection of the bar."""
    if sys.stderr.isatty():
        from tqdm import tqdm
        from tqdm.contrib.logging import logging_redirect_tqdm

        bar = tqdm(total=total, initial=initial, file=sys.stderr, unit=unit, dynamic_ncols=True,
                   desc=desc, smoothing=0.05)
        stack.enter_context(logging_redirect_tqdm())  # log lines above the bar, not through it
        return bar
    return _LineProgress(total, initial, desc=desc, unit=unit + "s")


def run_sweep(
    config: SweepConfig,
    *,
    output: str | Path | None = None,
    n_jobs: int | None = None,
    scheduler: str | None = None,
    solve_fn: SolveFn | None = None,
    warm_up_fn: Callable[[], Any] | None = None,
    progress: bool = True,
    retry_failed: bool = False,
    chunk_size: int | None = None,
    flush_interval_s: float = 60.0,
    consolidate_output: bool = True,
    append: bool = False,
    max_designs: int = MAX_DESIGNS,
    announce: Callable[[str], None] | None = None,
) -> SweepSummary:
    """Solve every design of ``config`` that is not recorded yet and consolidate the result file.

    Parameters
    ----------
    config
        The validated grid or point list (:func:`snapjump_cli.sweep.config.load_config`).
    output
        Result parquet file (default ``config.output``). Part files go to ``<output>.parts/``.
    n_jobs
        joblib ``n_jobs`` (default ``config.n_jobs``; 1 runs in-process, -1 uses every core).
        Ignored with ``scheduler`` (the cluster decides).
    scheduler
        Address of a dask.distributed scheduler; runs through joblib's dask backend.
    solve_fn, warm_up_fn
        The solver (default :func:`snapjump_cli.fe.solve.solve_design` and its ``warm_up``); tests and
        notebooks inject their own. ``solve_fn`` must be importable by reference or
        cloudpickle-able to reach the workers.
    progress
        Show progress on stderr: a tqdm bar on a terminal, else a plain line every 30 s.
    retry_failed
        Solve designs recorded as ``failed`` again.
    chunk_size, flush_interval_s
        Write a part file every ``chunk_size`` finished designs (default ``config.chunk_size``)
        or when ``flush_interval_s`` has passed since the last write, whichever comes first.
    consolidate_output
        Merge the parts into ``output`` at the end (else leave the parts; a later run merges).
    append
        Allow adding to an output that holds rows this run would not produce (another grid,
        mesh, solver or material). Without it such a run is refused before it starts.
    max_designs
        Refuse configs with more designs than this (a typo such as ``num: 1000000`` would
        otherwise run for weeks).
    announce
        Called once with a one-line summary (design counts, time estimate) before solving.

    Returns
    -------
    SweepSummary

    Raises
    ------
    SweepInputError
        Bad input: too many designs, the output is not writable or not a result file, another
        sweep holds its lock, it holds rows of other settings (without ``append``), or the
        scheduler is unreachable. Nothing is written.
    SweepError
        The pool broke in a way that no design can be blamed for. Rows finished so far are kept.
    """
    t_start = time.perf_counter()
    output = Path(output if output is not None else config.output)
    if (why := jobs_error(n_jobs if n_jobs is not None else config.n_jobs)):
        raise SweepInputError(f"-j/--jobs: {why}" if n_jobs is not None else f"{config.source}: n_jobs: {why}")
    n_jobs = int(n_jobs if n_jobs is not None else config.n_jobs)
    if config.n_designs > max_designs:
        raise SweepInputError(
            f"{config.source}: {config.n_designs} designs exceed the limit of {max_designs} "
            f"(~{_fmt_duration(estimate_seconds(config.n_designs, config.mesh, os.cpu_count() or 1))} on this "
            f"machine); check the grid, or raise the limit with --max-designs")
    if scheduler is not None:
        check_scheduler(scheduler)
    chunk = int(chunk_size if chunk_size is not None else config.chunk_size)
    if output.exists() and output.is_dir():
        raise SweepInputError(f"{output}: is a directory, expected a parquet file path")
    check_writable(output, SweepInputError)
    if follow_links(output) != output:  # a link: the shared file it points to is the output
        log.info("%s is a link to %s: writing that file (its lock and parts beside it)", output, follow_links(output))
        output = follow_links(output)
    parts = parts_dir(output)
    output.parent.mkdir(parents=True, exist_ok=True)  # the lock and the parts live beside the output

    with OutputLock(output):
        return _run_locked(config, output, parts, n_jobs, scheduler, solve_fn, warm_up_fn, progress, retry_failed,
                           chunk, flush_interval_s, consolidate_output, append, announce, t_start)


@dataclass
class _Plan:
    """What a run has to do: rows already recorded, invalid designs (rows ready), tasks to solve."""

    counts: dict[str, int]
    n_resumed: int
    invalid_rows: list[dict[str, Any]]
    tasks: list[dict[str, Any]]


def _plan(config: SweepConfig, points: list[DesignPoint], keys: list[str], done: dict[str, str],
          retry_failed: bool, stamp: dict[str, Any], limit_threads: bool) -> _Plan:
    """Sort the designs into recorded (skipped), invalid geometry (recorded here, never meshed) and
    tasks for the solver."""
    plan = _Plan(counts={s: 0 for s in res.STATUSES}, n_resumed=0, invalid_rows=[], tasks=[])
    for p, k in zip(points, keys):
        prev = done.get(k)
        if prev is not None and not (retry_failed and prev == "failed"):
            plan.counts[prev] = plan.counts.get(prev, 0) + 1
            plan.n_resumed += 1
            continue
        row = _base_row(p, k, config.mesh, stamp)
        try:
            design = Design(**p.design_kwargs())
        except InvalidDesign as e:
            row.update(status="invalid_geometry", error=str(e), finished_utc=now_utc(), t_total_s=0.0)
            plan.invalid_rows.append(row)
            continue
        task = {"row": row, "design": design, "mesh": config.mesh, "solver": config.solver,
                "limit_threads": limit_threads}
        if config.fluid.is_air:
            task["fluid"] = config.fluid
        plan.tasks.append(task)
    return plan


def _stamp(config: SweepConfig) -> dict[str, Any]:
    """The provenance every row of this run carries: code version and commit, solver settings."""
    from snapjump_cli import __version__

    git = res.git_commit()
    return {"snapjump_version": __version__,
            "git_commit": (git["commit"] + ("+dirty" if git.get("dirty") else "")) if git else None,
            "solver_settings": settings_json(_row_settings(config))}


def _row_settings(config: SweepConfig) -> dict[str, Any]:
    """The settings a row records: the solver's (without its resource limits), and the fluid when
    it is air (a water row's are as they were before the setting existed, so that ``rank`` sees
    water and air rows as mixed)."""
    out = config.solver.numerics()
    if config.fluid.is_air:
        out["fluid"] = config.fluid.as_dict()
    return out


def _solve_all(tasks: list[dict[str, Any]], solve_fn: SolveFn, warm_up_fn: Callable[[], Any] | None, n_jobs: int,
               scheduler: str | None, marker_dir: Path, record: Callable[[dict[str, Any]], None],
               clients: list[Any]) -> None:
    """Compile the kernels once (``warm_up_fn``), then solve every task (in-process, joblib
    processes, or a dask cluster, whose client is appended to ``clients`` for the caller to close)
    and ``record`` each row as it finishes."""
    backend = "loky"
    if scheduler is not None:
        if not clients:
            clients.append(connect(scheduler))
        backend, n_jobs = "dask", -1
    if warm_up_fn is not None:
        t0 = time.perf_counter()
        try:
            warm_up_fn()
        except Exception as e:  # noqa: BLE001 - reported as one line; -vv shows the traceback
            log.debug("warm-up failed", exc_info=True)
            raise SweepError(f"the solver warm-up (kernel compilation) failed: {type(e).__name__}: {e}") from e
        log.info("solver kernels compiled in %.1f s", time.perf_counter() - t0)
    md = None
    if n_jobs != 1 or backend != "loky":
        own_folder(marker_dir, SweepInputError)
        md = marker_dir
    if backend == "dask":
        from joblib import parallel_config

        with parallel_config(backend="dask", client=clients[-1]):
            for row in execute(tasks, solve_fn, n_jobs, backend, md):
                record(row)
    else:
        for row in execute(tasks, solve_fn, n_jobs, backend, md):
            record(row)


def _run_locked(config: SweepConfig, output: Path, parts: Path, n_jobs: int, scheduler: str | None,
                solve_fn: SolveFn | None, warm_up_fn: Callable[[], Any] | None, progress: bool, retry_failed: bool,
                chunk: int, flush_interval_s: float, consolidate_output: bool, append: bool,
                announce: Callable[[str], None] | None, t_start: float) -> SweepSummary:
    done = done_keys(output)
    points = list(config.designs())
    keys = [design_key(p, config.mesh, config.solver, config.fluid) for p in points]
    cfg_dict = config.to_dict()
    if not append:
        check_compatible(output, set(keys), cfg_dict)
    order = {k: p.index for k, p in zip(keys, points)}
    plan = _plan(config, points, keys, done, retry_failed, _stamp(config), scheduler is not None)
    counts, n_resumed, invalid_rows, tasks = plan.counts, plan.n_resumed, plan.invalid_rows, plan.tasks
    if n_resumed:
        log.info("resuming %s: %d of %d designs already recorded", output, n_resumed, len(points))
    workers = (os.cpu_count() or 1) if n_jobs < 0 else n_jobs
    if announce is not None:
        est = estimate_seconds(len(tasks), config.mesh, workers, config.solver, slowdown=load_factor())
        announce(f"sweep: {len(points)} designs ({n_resumed} already recorded, {len(invalid_rows)} invalid geometry, "
                 f"{len(tasks)} to solve" + (f" on {workers} worker{'s' if workers != 1 else ''}, roughly "
                                             f"{_fmt_duration(est)}" if tasks and scheduler is None else "") + ")")

    solver_name = None
    if tasks:
        if solve_fn is None:
            solve_fn, default_warm_up = default_solver()
            warm_up_fn = warm_up_fn or default_warm_up
            solver_name = "snapjump_cli.fe.solve:solve_design"
        else:
            solver_name = f"{getattr(solve_fn, '__module__', '?')}:{getattr(solve_fn, '__qualname__', '?')}"
    meta = res.provenance(cfg_dict, command="sweep", solver=solver_name, output=str(output), n_jobs=n_jobs,
                          scheduler=scheduler, key_version=KEY_VERSION)

    own_folder(parts, SweepInputError)  # a real folder, never a link (nothing is followed in it)
    marker_dir = parts / "running"
    remove_own_folder(marker_dir, MARKER_NAME)  # stale markers of a killed run (we hold the lock)
    if os.path.lexists(marker_dir):  # something else left there: a real folder is used, a link refused
        own_folder(marker_dir, SweepInputError)
    writer = PartWriter(parts, meta, chunk, flush_interval_s)

    bar = None
    stack = ExitStack()
    if progress:  # the invalid designs cost nothing: counted as done from the start, out of the rate
        bar = make_progress(len(points), n_resumed + len(invalid_rows), stack)

    def record(row: dict[str, Any], advance: bool = True) -> None:
        counts[row["status"]] = counts.get(row["status"], 0) + 1
        writer.add(row)
        if bar is not None:
            bar.set_postfix({"ok": counts["ok"], "no_snap": counts["no_snap"], "invalid": counts["invalid_geometry"],
                             "failed": counts["failed"]}, refresh=False)
            if advance:
                bar.update(1)

    clients: list[Any] = []
    stopped_by: BaseException | None = None
    try:
        if scheduler is not None and tasks:  # reached before any row is written (a bad address writes nothing)
            clients.append(connect(scheduler))
        for row in invalid_rows:
            record(row, advance=False)
        if tasks:
            _solve_all(tasks, solve_fn, warm_up_fn, n_jobs, scheduler, marker_dir, record, clients)
    except BaseException as exc:
        stopped_by = exc
        raise
    finally:
        try:
            writer.flush()  # keep every finished row, also on Ctrl-C or errors
        except OSError as e:  # after another error: that one is reported (once, if it is this one)
            if stopped_by is None:
                raise
            if not isinstance(stopped_by, OSError):
                log.warning("could not write the last %d finished rows: %s", len(writer.buffer), e)
        stack.close()
        if bar is not None:
            bar.close()
        for client in clients:
            client.close()
        remove_own_folder(marker_dir, MARKER_NAME)
        if stopped_by is not None:  # stopped before any row (an unreachable scheduler): no empty folder left
            remove_own_folder(parts)

    if consolidate_output and (tasks or invalid_rows or part_files(parts) or not output.exists()):
        counts = consolidate(output, meta, order)
    else:
        remove_own_folder(parts)
    summary = SweepSummary(output=output, n_designs=len(points), n_resumed=n_resumed, n_solved=len(tasks),
                           counts=counts, wall_s=time.perf_counter() - t_start)
    log.info("sweep done in %.1f s: %s", summary.wall_s, ", ".join(f"{k}={v}" for k, v in counts.items()))
    return summary
