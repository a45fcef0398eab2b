"""Solve a grid of designs in parallel into a chunked, resumable parquet result.

Flow
----
1. Every grid point gets a stable key, :func:`design_key` (a SHA-256 of the design parameters and
   the mesh + solver settings). Keys already present in ``<out>`` or in ``<out>.parts/`` are
   skipped (resume); ``retry_failed=True`` solves ``failed`` ones again.
2. Designs that raise :class:`~snapjump_cli.geometry.InvalidDesign` on construction are recorded
   as ``invalid_geometry`` in the parent and never meshed.
3. The solver kernels are compiled once in the parent (``warm_up()``), then the remaining designs
   are mapped with joblib: the loky process backend with every BLAS/OpenMP/numba thread pool
   capped to 1 per worker (joblib's ``inner_max_num_threads=1`` sets ``OMP_NUM_THREADS``,
   ``OPENBLAS_NUM_THREADS``, ``MKL_NUM_THREADS``, ``NUMBA_NUM_THREADS``, ... in the workers'
   environment when the pool starts), or, with ``scheduler=ADDRESS``, a dask.distributed cluster
   through joblib's dask backend. Results arrive as they finish (``return_as="generator_unordered"``).
4. Finished rows are buffered and written every ``chunk_size`` rows (or ``flush_interval_s``
   seconds) as ``<out>.parts/part-NNNNNN.parquet``, each atomically (temporary file +
   ``os.replace``), so a killed sweep loses at most the rows of one unwritten chunk.
5. At the end all parts (and a previous ``<out>``, if any) are consolidated into ``<out>``
   (atomically, deduplicated by key, in grid order) and the parts folder is removed.

Failures
--------
Any exception raised while meshing/solving a design (including ``SolveFailed``) is caught in the
worker: the row is ``failed`` with the exception text. A result that claims a snap but holds a
NaN/inf metric is also ``failed``. If a worker *process* dies (segfault, OOM kill), the designs
that were running (tracked by marker files in ``<out>.parts/running/``) are re-run one at a time
in a fresh worker; the one that kills its worker again is recorded as ``failed``.

Test-only hook
--------------
If no ``solve_fn`` is passed and the environment variable ``SNAPJUMP_FAKE_SOLVER=module:function``
is set, that function replaces :func:`snapjump_cli.solve.solve_design` (and ``module.warm_up``, if
present, replaces ``snapjump_cli.solve.warm_up``). It exists so that tests can kill a real
``snapjump sweep`` subprocess mid-run with a cheap, slow fake solver. A warning is logged and the
solver used is recorded in the provenance metadata (``solver``).
"""
from __future__ import annotations

import hashlib
import importlib
import json
import logging
import math
import os
import shutil
import socket
import sys
import time
from contextlib import ExitStack
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping

from snapjump_cli import results as res
from snapjump_cli.config import DesignPoint, SweepConfig
from snapjump_cli.geometry import Design, InvalidDesign, centre_offset, outer_radius
from snapjump_cli.settings import RESULT_KEYS, MeshSettings, SolverSettings

__all__ = [
    "FAKE_SOLVER_ENV",
    "KEY_VERSION",
    "SweepError",
    "SweepInputError",
    "SweepSummary",
    "design_key",
    "parts_dir",
    "done_keys",
    "resolve_solver",
    "consolidate",
    "run_sweep",
]

log = logging.getLogger(__name__)

#: Environment variable of the test-only solver hook (``module:function``).
FAKE_SOLVER_ENV = "SNAPJUMP_FAKE_SOLVER"
#: Bumped whenever the meaning of a key changes (old results are then not reused).
KEY_VERSION = "snapjump-sweep-v1"
_CONNECT_TIMEOUT_S = 15.0

SolveFn = Callable[[Design, MeshSettings, SolverSettings], Mapping[str, Any]]


class SweepError(RuntimeError):
    """The sweep itself cannot proceed (not a single design's failure)."""


class SweepInputError(SweepError):
    """The sweep cannot start because of the user's input (output path, scheduler, n_jobs)."""


@dataclass
class SweepSummary:
    """What a sweep did.

    Attributes
    ----------
    output : Path
        The consolidated result file.
    n_designs : int
        Grid size.
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


# ---- keys and paths --------------------------------------------------------------------------
def design_key(point: DesignPoint | Design | Mapping[str, Any], mesh: MeshSettings, solver: SolverSettings) -> str:
    """A stable hash of a design's parameters and the mesh + solver settings.

    The key does not depend on the grid the design came from, on the order of the grid, on the
    output path or on the number of jobs, so a resumed (or extended) sweep recognises the designs
    it has already solved.

    Parameters
    ----------
    point
        A grid point, a :class:`Design` or a mapping with the fields of :data:`results.INPUT_COLUMNS`.
    mesh, solver
        The numerical settings.

    Returns
    -------
    str
        24 hexadecimal characters.
    """
    src = point if isinstance(point, Mapping) else point.__dict__
    payload = {
        "v": KEY_VERSION,
        "design": {c: float(src[c]) for c in res.INPUT_COLUMNS},
        "mesh": _typed(mesh.as_dict()),
        "solver": _typed(solver.as_dict()),
    }
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def _typed(d: Mapping[str, Any]) -> dict[str, Any]:
    out = {}
    for k, v in d.items():
        if isinstance(v, bool) or isinstance(v, str):
            out[k] = v
        elif isinstance(v, int):
            out[k] = int(v)
        else:
            out[k] = float(v)
    return out


def parts_dir(output: str | Path) -> Path:
    """The folder of part files of ``output``: ``<output>.parts``."""
    output = Path(output)
    return output.with_name(output.name + ".parts")


def _part_files(parts: Path) -> list[Path]:
    return sorted(parts.glob("part-*.parquet")) if parts.is_dir() else []


def _read_keys(path: Path) -> Any:
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        t = pq.read_table(path, columns=["key", "status"])
    except (pa.ArrowInvalid, KeyError, OSError) as e:
        raise SweepInputError(f"{path}: not a readable snapjump result file ({e})") from None
    return t


def done_keys(output: str | Path) -> dict[str, str]:
    """Keys already recorded for ``output`` (its consolidated file and its part files).

    Returns
    -------
    dict
        key -> status (the most recent record wins).
    """
    output = Path(output)
    done: dict[str, str] = {}
    files = ([output] if output.exists() else []) + _part_files(parts_dir(output))
    for f in files:
        t = _read_keys(f)
        done.update(zip(t.column("key").to_pylist(), t.column("status").to_pylist()))
    return done


# ---- solver resolution ---------------------------------------------------------------------------
def _import_target(spec: str) -> tuple[Callable, Any]:
    mod_name, sep, fn_name = spec.partition(":")
    if not sep or not mod_name or not fn_name:
        raise SweepInputError(f"{FAKE_SOLVER_ENV}={spec!r}: expected 'module:function'")
    try:
        mod = importlib.import_module(mod_name)
        fn = getattr(mod, fn_name)
    except (ImportError, AttributeError) as e:
        raise SweepInputError(f"{FAKE_SOLVER_ENV}={spec!r}: cannot import ({e})") from None
    return fn, mod


def resolve_solver(solve_fn: SolveFn | None = None, warm_up_fn: Callable[[], Any] | None = None
                   ) -> tuple[SolveFn, Callable[[], Any] | None, str]:
    """Choose the solve function.

    Parameters
    ----------
    solve_fn, warm_up_fn
        Injected functions (tests, notebooks). ``solve_fn`` must be importable by reference or
        cloudpickle-able to reach the workers.

    Returns
    -------
    (solve_fn, warm_up_fn, name)
        Without injection: ``snapjump_cli.solve.solve_design`` and ``warm_up``, unless the
        test-only hook ``SNAPJUMP_FAKE_SOLVER=module:function`` is set.
    """
    if solve_fn is not None:
        return solve_fn, warm_up_fn, f"{getattr(solve_fn, '__module__', '?')}:{getattr(solve_fn, '__qualname__', '?')}"
    spec = os.environ.get(FAKE_SOLVER_ENV)
    if spec:
        fn, mod = _import_target(spec)
        log.warning("using the test-only solver %s (from %s)", spec, FAKE_SOLVER_ENV)
        return fn, warm_up_fn or getattr(mod, "warm_up", None), spec
    try:
        from snapjump_cli import solve  # lazily: heavy (numba, gmsh)
    except ImportError as e:
        log.debug("importing snapjump_cli.solve failed", exc_info=True)
        raise SweepError(f"cannot import the solver snapjump_cli.solve: {e}") from e

    return solve.solve_design, warm_up_fn or getattr(solve, "warm_up", None), "snapjump_cli.solve:solve_design"


# ---- rows ----------------------------------------------------------------------------------------
def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def _base_row(point: DesignPoint, key: str, mesh: MeshSettings) -> dict[str, Any]:
    row: dict[str, Any] = {"key": key, "index": point.index, "status": None, "error": ""}
    row.update(point.design_kwargs())
    row.update(mesh_order=mesh.order, mesh_nt=mesh.nt, mesh_aspect=float(mesh.aspect))
    try:
        args = (point.eta_i, math.radians(point.theta_i_deg), point.eta_o, math.radians(point.theta_o_deg), point.R_i)
        row["R_o"] = outer_radius(*args)
        row["Delta"] = centre_offset(*args)
    except (InvalidDesign, ValueError, ZeroDivisionError):
        row["R_o"] = row["Delta"] = None
    return row


def _coerce(key: str, v: Any) -> Any:
    if v is None:
        return None
    if key in res.BOOL_RESULT_KEYS:
        return bool(v)
    if key in res.STR_RESULT_KEYS:
        return str(v)
    if key in res.INT_RESULT_KEYS:
        x = float(v)
        if not math.isfinite(x):
            return None
        return int(v)
    return float(v)


def _result_to_row(row: dict[str, Any], result: Any) -> None:
    """Fill ``row`` from a solver result; decide ``ok`` / ``no_snap`` / ``failed``."""
    if not isinstance(result, Mapping):
        row.update(status="failed", error=f"solver returned {type(result).__name__}, expected a dict")
        return
    missing = [k for k in RESULT_KEYS if k not in result]
    values: dict[str, Any] = {}
    bad_type = []
    for k in RESULT_KEYS:
        if k in result:
            try:
                values[k] = _coerce(k, result[k])
            except (TypeError, ValueError, OverflowError):
                bad_type.append(f"{k}={result[k]!r}")
                values[k] = None
    nonfinite = [k for k in res.FLOAT_RESULT_KEYS if values.get(k) is not None and not math.isfinite(values[k])]
    absent = [k for k in res.FLOAT_RESULT_KEYS if k in result and values.get(k) is None and k not in bad_type]
    absent = [k for k in absent if k not in res.OPTIONAL_FLOAT_KEYS]
    if values.get("lower_state_method") == "descent":
        # a lower state found by energy descent is not on the traced path: no path integral
        absent = [k for k in absent if k not in ("dE_path_J", "dE_rel_diff")]
    snaps = bool(values.get("snaps"))
    status, error = ("ok" if snaps else "no_snap"), ""
    if missing:
        status, error = "failed", "solver result lacks keys: " + ", ".join(missing)
    elif bad_type:
        status, error = "failed", "solver result has values of the wrong type: " + ", ".join(bad_type)
    elif status == "ok" and (nonfinite or absent):
        status = "failed"
        error = "non-finite metrics in a snapping result: " + ", ".join(
            [f"{k}={values[k]}" for k in nonfinite] + [f"{k}=None" for k in absent])
    for k in nonfinite:  # never store inf; NaN only as null
        values[k] = None
    row.update(values)
    row.update(status=status, error=error)


def _limit_threads_in_worker() -> None:
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


def _solve_task(task: dict[str, Any], solve_fn: SolveFn, marker_dir: str | None) -> dict[str, Any]:
    """Worker: solve one design and return its row (never raises for a design's failure)."""
    t0 = time.perf_counter()
    row = dict(task["row"])
    marker = None
    if marker_dir is not None:
        try:
            marker = Path(marker_dir) / row["key"]
            marker.write_text(f"{os.getpid()}\n")
        except OSError:
            marker = None
    try:
        if task.get("limit_threads"):
            _limit_threads_in_worker()
        result = solve_fn(task["design"], task["mesh"], task["solver"])
        _result_to_row(row, result)
    except Exception as e:  # noqa: BLE001 - any failure of one design is recorded, never raised
        msg = str(e).strip().replace("\n", " | ")
        row.update(status="failed", error=f"{type(e).__name__}: {msg}"[:4000])
    row.update(t_total_s=time.perf_counter() - t0, host=socket.gethostname(), pid=os.getpid(), finished_utc=_now())
    if marker is not None:
        try:
            marker.unlink()
        except OSError:
            pass
    return row


# ---- chunked writer -------------------------------------------------------------------------------
class _PartWriter:
    """Buffers rows and writes them as atomic part files ``part-NNNNNN.parquet``."""

    def __init__(self, parts: Path, meta: dict[str, Any], chunk_size: int, flush_interval_s: float) -> None:
        self.parts = parts
        self.meta = meta
        self.chunk_size = max(1, int(chunk_size))
        self.flush_interval_s = flush_interval_s
        self.buffer: list[dict[str, Any]] = []
        existing = [int(p.stem.split("-")[1]) for p in _part_files(parts) if p.stem.split("-")[1].isdigit()]
        self.seq = max(existing, default=-1) + 1
        self.last_flush = time.monotonic()
        self.n_written = 0

    def add(self, row: dict[str, Any]) -> None:
        self.buffer.append(row)
        if len(self.buffer) >= self.chunk_size or time.monotonic() - self.last_flush >= self.flush_interval_s:
            self.flush()

    def flush(self) -> None:
        if not self.buffer:
            return
        path = self.parts / f"part-{self.seq:06d}.parquet"
        res.write_table_atomic(res.rows_to_table(self.buffer, self.meta), path)
        log.debug("wrote %s (%d rows)", path, len(self.buffer))
        self.n_written += len(self.buffer)
        self.seq += 1
        self.buffer = []
        self.last_flush = time.monotonic()


# ---- consolidation --------------------------------------------------------------------------------
def consolidate(output: str | Path, meta: Mapping[str, Any], order: Mapping[str, int] | None = None) -> dict[str, int]:
    """Merge ``<output>`` (if any) and its part files into ``<output>``, atomically.

    Rows are deduplicated by key (the newest record wins), rows of the current grid (``order``:
    key -> grid index) come first in grid order, others (from an earlier, different grid) after.
    The parts folder is removed once the consolidated file is in place.

    Returns
    -------
    dict
        Rows per status in the consolidated file.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    output = Path(output)
    parts = parts_dir(output)
    files = ([output] if output.exists() else []) + _part_files(parts)
    schema = res.result_schema()
    tables = []
    for f in files:
        t = pq.read_table(f)
        t = t.replace_schema_metadata(None)
        # tolerate files written with an older column set: add the missing columns as nulls
        for fld in schema:
            if fld.name not in t.column_names:
                t = t.append_column(fld, pa.nulls(len(t), type=fld.type))
        tables.append(t.select(schema.names).cast(schema))
    if tables:
        df = pa.concat_tables(tables).to_pandas(types_mapper=res.pandas_types_mapper())
    else:
        df = res.rows_to_table([]).to_pandas(types_mapper=res.pandas_types_mapper())
    df = df.drop_duplicates(subset="key", keep="last")
    order = dict(order or {})
    in_grid = df["key"].map(lambda k: k in order).astype(bool)
    extra = int((~in_grid).sum())
    if extra:
        log.warning("%s: %d rows from an earlier, different grid are kept after this grid's rows", output, extra)
    df.loc[in_grid, "index"] = df.loc[in_grid, "key"].map(order).astype("int64")
    df = df.assign(_g=~in_grid).sort_values(["_g", "index", "key"], kind="stable").drop(columns="_g")
    counts = {s: int((df["status"] == s).sum()) for s in res.STATUSES}
    full_meta = dict(meta)
    full_meta.update(n_rows=int(len(df)), status_counts=counts, consolidated_utc=_now())
    table = pa.Table.from_pandas(df, schema=schema, preserve_index=False)
    res.write_table_atomic(res._with_metadata(table, full_meta), output)
    if parts.is_dir():
        shutil.rmtree(parts, ignore_errors=True)
    return counts


# ---- execution ------------------------------------------------------------------------------------
def _parallel_rows(tasks: list[dict[str, Any]], solve_fn: SolveFn, n_jobs: int, backend: str,
                   marker_dir: str | None) -> Iterator[dict[str, Any]]:
    from joblib import Parallel, delayed, parallel_config

    kwargs: dict[str, Any] = {}
    if backend == "loky":
        kwargs["inner_max_num_threads"] = 1
    with parallel_config(backend=backend, **kwargs) if backend == "loky" else ExitStack():
        par = Parallel(n_jobs=n_jobs, return_as="generator_unordered", pre_dispatch="2*n_jobs")
        yield from par(delayed(_solve_task)(t, solve_fn, marker_dir) for t in tasks)


def _execute(tasks: list[dict[str, Any]], solve_fn: SolveFn, n_jobs: int, backend: str,
             marker_dir: Path | None) -> Iterator[dict[str, Any]]:
    """Yield one row per task, surviving the death of worker processes."""
    if n_jobs == 1 and backend == "loky":  # sequential, in-process
        for t in tasks:
            yield _solve_task(t, solve_fn, None)
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
            suspects = [p.name for p in marker_dir.iterdir()] if marker_dir is not None and marker_dir.is_dir() else []
            for p in suspects:
                (marker_dir / p).unlink(missing_ok=True)
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
                    (marker_dir / key).unlink(missing_ok=True)
                    row = dict(task["row"])
                    row.update(status="failed", finished_utc=_now(),
                               error=f"worker process died while solving this design ({type(exc2).__name__}: {exc2})"[:4000])
                yield row


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
) -> SweepSummary:
    """Solve every design of ``config`` that is not recorded yet and consolidate the result file.

    Parameters
    ----------
    config
        The validated grid (:func:`snapjump_cli.config.load_config`).
    output
        Result parquet file (default ``config.output``). Part files go to ``<output>.parts/``.
    n_jobs
        joblib ``n_jobs`` (default ``config.n_jobs``; 1 runs in-process, -1 uses every core).
        Ignored with ``scheduler`` (the cluster decides).
    scheduler
        Address of a dask.distributed scheduler; runs through joblib's dask backend.
    solve_fn, warm_up_fn
        Injected solver (default: :func:`snapjump_cli.solve.solve_design` / ``warm_up``; see
        the module docstring for the test-only environment hook).
    progress
        Show a tqdm progress bar on stderr (ETA and counts per status).
    retry_failed
        Solve designs recorded as ``failed`` again.
    chunk_size, flush_interval_s
        Write a part file every ``chunk_size`` finished designs (default ``config.chunk_size``)
        or when ``flush_interval_s`` has passed since the last write, whichever comes first.
    consolidate_output
        Merge the parts into ``output`` at the end (else leave the parts; a later run merges).

    Returns
    -------
    SweepSummary

    Raises
    ------
    SweepError
        The existing output is not a result file, the scheduler is unreachable, or the pool
        broke in a way that no design can be blamed for. Rows finished so far are kept.
    """
    t_start = time.perf_counter()
    output = Path(output if output is not None else config.output)
    n_jobs = int(n_jobs if n_jobs is not None else config.n_jobs)
    if n_jobs == 0:
        raise SweepInputError("n_jobs must not be 0")
    chunk = int(chunk_size if chunk_size is not None else config.chunk_size)
    parts = parts_dir(output)
    if output.exists() and output.is_dir():
        raise SweepInputError(f"{output}: is a directory, expected a parquet file path")

    done = done_keys(output)
    points = list(config.designs())
    keys = [design_key(p, config.mesh, config.solver) for p in points]
    order = {k: p.index for k, p in zip(keys, points)}
    counts = {s: 0 for s in res.STATUSES}
    invalid_rows: list[dict[str, Any]] = []
    tasks: list[dict[str, Any]] = []
    n_resumed = 0
    for p, k in zip(points, keys):
        prev = done.get(k)
        if prev is not None and not (retry_failed and prev == "failed"):
            counts[prev] = counts.get(prev, 0) + 1
            n_resumed += 1
            continue
        row = _base_row(p, k, config.mesh)
        try:
            design = Design(**p.design_kwargs())
        except InvalidDesign as e:
            row.update(status="invalid_geometry", error=str(e), finished_utc=_now(), t_total_s=0.0)
            invalid_rows.append(row)
            continue
        tasks.append({"row": row, "design": design, "mesh": config.mesh, "solver": config.solver,
                      "limit_threads": scheduler is not None})
    if n_resumed:
        log.info("resuming %s: %d of %d designs already recorded", output, n_resumed, len(points))

    meta_base = {"config": config.to_dict(), "output": str(output), "n_jobs": n_jobs, "scheduler": scheduler,
                 "key_version": KEY_VERSION}
    solver_name = None
    if tasks:
        solve_fn, warm_up_fn, solver_name = resolve_solver(solve_fn, warm_up_fn)
    meta = res.provenance(meta_base["config"], command="sweep", solver=solver_name,
                          **{k: v for k, v in meta_base.items() if k != "config"})

    parts.mkdir(parents=True, exist_ok=True)
    marker_dir = parts / "running"
    shutil.rmtree(marker_dir, ignore_errors=True)  # stale markers of a killed run
    writer = _PartWriter(parts, meta, chunk, flush_interval_s)

    bar = None
    stack = ExitStack()
    if progress:
        from tqdm import tqdm
        from tqdm.contrib.logging import logging_redirect_tqdm

        bar = tqdm(total=len(points), initial=n_resumed, file=sys.stderr, unit="design", dynamic_ncols=True,
                   desc="sweep", smoothing=0.05)
        stack.enter_context(logging_redirect_tqdm())  # log lines above the bar, not through it

    def record(row: dict[str, Any]) -> None:
        counts[row["status"]] = counts.get(row["status"], 0) + 1
        writer.add(row)
        if bar is not None:
            bar.update(1)
            bar.set_postfix({"ok": counts["ok"], "no_snap": counts["no_snap"], "invalid": counts["invalid_geometry"],
                             "failed": counts["failed"]}, refresh=False)

    client = None
    try:
        for row in invalid_rows:
            record(row)
        if tasks:
            backend = "loky"
            if scheduler is not None:
                backend, client = "dask", _connect(scheduler)
                n_jobs = -1
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
                marker_dir.mkdir(parents=True, exist_ok=True)
                md = marker_dir
            if backend == "dask":
                from joblib import parallel_config

                with parallel_config(backend="dask", client=client):
                    for row in _execute(tasks, solve_fn, n_jobs, backend, md):
                        record(row)
            else:
                for row in _execute(tasks, solve_fn, n_jobs, backend, md):
                    record(row)
    finally:
        writer.flush()  # keep every finished row, also on Ctrl-C or errors
        stack.close()
        if bar is not None:
            bar.close()
        if client is not None:
            client.close()
        shutil.rmtree(marker_dir, ignore_errors=True)

    if consolidate_output and (tasks or invalid_rows or _part_files(parts) or not output.exists()):
        counts = consolidate(output, meta, order)
    elif parts.is_dir() and not any(parts.iterdir()):
        parts.rmdir()
    summary = SweepSummary(output=output, n_designs=len(points), n_resumed=n_resumed, n_solved=len(tasks),
                           counts=counts, wall_s=time.perf_counter() - t_start)
    log.info("sweep done in %.1f s: %s", summary.wall_s, ", ".join(f"{k}={v}" for k, v in counts.items()))
    return summary


def _connect(address: str) -> Any:
    """A dask.distributed client for ``address`` (dask imported here only)."""
    try:
        from dask.distributed import Client
    except ImportError as e:  # pragma: no cover - depends on the install
        raise SweepError("--scheduler needs dask[distributed] (pip install 'snapjump[dask]')") from e
    try:
        return Client(address, timeout=_CONNECT_TIMEOUT_S, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as e:
        raise SweepInputError(f"cannot connect to the dask scheduler at {address!r}: {e}") from None
