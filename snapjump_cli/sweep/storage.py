"""Where a sweep's rows live: design keys, part files, the output lock and consolidation.

Layout of an output ``OUT.parquet``:

* ``OUT.parquet`` - the consolidated result (sorted, one row per key);
* ``OUT.parquet.parts/part-NNNNNN.parquet`` - rows of the running (or a killed) sweep, each part
  written atomically, so a killed sweep loses at most the rows of one unwritten chunk;
* ``OUT.parquet.lock`` - held by the sweep writing into ``OUT`` (pid, host, start time), so that
  two sweeps never write into one output (a lock whose process is gone is taken over).

A design's key (:func:`design_key`) hashes its parameters and the mesh + solver settings, so a
resumed or extended sweep recognises the designs already solved, and rows computed with other
settings never share a key with this run's.
"""
from __future__ import annotations

import hashlib
import json
import logging
import os
import re
import time
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Mapping

from snapjump_cli.sweep import results as res
from snapjump_cli.sweep.config import DesignPoint
from snapjump_cli.errors import SweepInputError
from snapjump_cli.fe.axisym.fluid import FluidSettings
from snapjump_cli import files
from snapjump_cli.files import lock_path, own_files, remove_own, remove_own_folder
from snapjump_cli.geometry.caps import Design
from snapjump_cli.settings import MeshSettings, SolverSettings, without_limits

__all__ = [
    "KEY_VERSION",
    "design_key",
    "parts_dir",
    "part_files",
    "result_files",
    "lock_path",
    "done_keys",
    "OutputLock",
    "PartWriter",
    "remove_working_files",
    "consolidate",
    "check_compatible",
]

log = logging.getLogger(__name__)

#: Bumped whenever the meaning of a key changes (old results are then not reused). v2: ``ds0`` is
#: used as given (v1 keys hashed a ds0 that the continuation multiplied by 2.5).
KEY_VERSION = "snapjump-sweep-v2"


def now_utc() -> str:
    """The current UTC time, ISO 8601 to the second."""
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def design_key(point: DesignPoint | Design | Mapping[str, Any], mesh: MeshSettings, solver: SolverSettings,
               fluid: "FluidSettings | None" = None) -> str:
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
    fluid
        The fluid (:class:`snapjump_cli.fe.axisym.fluid.FluidSettings`); water (the default) leaves the key
        as it was before the setting existed.

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
        "solver": _typed(_key_settings(solver)),
    }
    if fluid is not None and fluid.is_air:
        payload["fluid"] = _typed(fluid.as_dict())
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:24]


#: Solver settings added after KEY_VERSION v2 with the value that leaves the computation as it was:
#: left out of the key at that value, so rows computed before the setting existed are still found
#: (``follow_mode`` was a limit setting, out of the key, before its actuator mode could land elsewhere
#: than the reference: rows of the default mode are still found).
_NEUTRAL_SETTINGS = {"harmonics": 0, "follow": False, "follow_N": 0, "margins": False, "follow_mode": "actuator"}


def _key_settings(solver: SolverSettings) -> dict[str, Any]:
    return {k: v for k, v in solver.numerics().items() if not (k in _NEUTRAL_SETTINGS and v == _NEUTRAL_SETTINGS[k])}


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


#: The names of the files a sweep writes into its parts folder: part files, their temporary files
#: (:func:`snapjump_cli.files.write_atomic`) and, in ``running/``, one marker per design being solved.
PART_NAME = re.compile(r"part-(\d{6,})\.parquet")
PART_TMP_NAME = re.compile(r"\.part-\d{6,}\..*\.tmp\.parquet")
MARKER_NAME = re.compile(r"[0-9a-f]{24}")


def part_files(parts: Path) -> list[Path]:
    """The part files in the folder ``parts`` (none if there is no such folder), in name order:
    regular files only (a link or anything else with such a name is not the sweep's: it is
    ignored with a warning and never followed, :func:`snapjump_cli.files.own_files`)."""
    return own_files(parts, PART_NAME)


def result_files(output: str | Path) -> list[Path]:
    """The files that hold the rows of ``output``: the file itself if it exists, then the part
    files of an unfinished (or resumed) run."""
    output = Path(output)
    return ([output] if output.is_file() else []) + part_files(parts_dir(output))


def _read_keys(path: Path) -> Any:
    try:
        t = res.read_table(path, columns=["key", "status"])
    except res.ResultsFileError as e:
        why = str(e).removeprefix(f"{path}: ")
        if path.parent.name.endswith(".parts"):  # a part of an interrupted run: its rows are solved again
            raise SweepInputError(f"{path}: damaged part file ({why}); delete this file and run the same command "
                                  f"again (its designs are solved again, the other parts are kept)") from None
        raise SweepInputError(f"{path}: not a readable snapjump result file ({why}); move it away or choose "
                              f"another output") from None
    return t


def done_keys(output: str | Path) -> dict[str, str]:
    """Keys already recorded for ``output`` (its consolidated file and its part files).

    Only rows whose status is one the sweep writes (:data:`results.STATUSES`) count as recorded:
    a row with any other status (edited by hand, written by another tool) is solved again, with a
    warning naming the file and the statuses.

    Returns
    -------
    dict
        key -> status (the most recent record wins).
    """
    output = Path(output)
    done: dict[str, str] = {}
    files = ([output] if output.is_file() else []) + part_files(parts_dir(output))
    for f in files:
        t = _read_keys(f)
        keys, statuses = t.column("key").to_pylist(), t.column("status").to_pylist()
        other = sorted({str(s) for s in statuses if s not in res.STATUSES})
        if other:
            n = sum(s not in res.STATUSES for s in statuses)
            log.warning("%s: %d rows have a status snapjump does not write (%s); their designs are solved again",
                        f, n, ", ".join(repr(s) for s in other))
        done.update((k, s) for k, s in zip(keys, statuses) if s in res.STATUSES and isinstance(k, str))
    return done



class OutputLock(files.OutputLock):
    """:class:`snapjump_cli.files.OutputLock` raising :class:`SweepInputError` (taken by ``sweep`` and
    ``optimize``): a second sweep into the same output is refused, naming the holder's pid, host
    and start time; a lock whose process is gone, or whose pid was reused, is taken over."""

    def __init__(self, output: str | Path, command: str = "sweep") -> None:
        super().__init__(output, command, error=SweepInputError)


def check_compatible(output: str | Path, keys: set[str], config: Mapping[str, Any]) -> None:
    """Refuse to mix runs: every row already in ``output`` (or its parts) must be one of ``keys``.

    A resumed run, or one over a larger grid, passes. Rows of another grid, mesh, solver or
    material (whose keys this run would never produce) make it raise :class:`SweepInputError`
    saying what differs from the file's recorded configuration; pass ``append=True`` to
    :func:`snapjump_cli.sweep.run.run_sweep` (``--append``) to add to such a file deliberately.
    """
    output = Path(output)
    stale = [k for k in done_keys(output) if k not in keys]
    if not stale:
        return
    files = ([output] if output.exists() else []) + part_files(parts_dir(output))
    old = {}
    for f in files:
        try:
            old = res.read_metadata(f).get("config") or {}
        except Exception:  # noqa: BLE001 - an unreadable file is reported by done_keys already
            old = {}
        if old:
            break
    diffs = []
    for k in ("mesh", "solver", "materials", "ring", "R_i", "fluid"):
        a, b = (without_limits(old.get(k)), without_limits(config.get(k))) if k == "solver" else (old.get(k), config.get(k))
        if k in old and a != b:
            diffs.append(f"{k} {a} -> {b}")
    grid_old = old.get("points", old.get("grid"))
    grid_new = config.get("points", config.get("grid"))
    if grid_old is not None and not _same_designs(grid_old, grid_new):
        diffs.append("the designs (grid or points)")
    what = "; ".join(diffs) if diffs else "its rows were computed for other designs or settings"
    raise SweepInputError(
        f"{output}: holds {len(stale)} rows that this run would not produce ({what}); "
        f"write to another output, or pass --append to add to this file deliberately")


def designs_digest(designs: Any) -> dict[str, Any]:
    """A short stand-in for a config's ``grid`` or ``points`` (their count and SHA-256)."""
    text = json.dumps(designs, sort_keys=True, separators=(",", ":"), default=str)
    n = len(designs) if isinstance(designs, list) else sum(len(v) for v in designs.values()) \
        if isinstance(designs, Mapping) else None
    return {"sha256": hashlib.sha256(text.encode()).hexdigest(), "n": n}


def part_meta(meta: Mapping[str, Any]) -> dict[str, Any]:
    """The provenance a part file carries: the run's, with the designs (``grid`` / ``points``) as
    a digest (:func:`designs_digest`). The full list is stored once, in the consolidated file;
    carried by every part it made the parts grow as the square of the number of designs."""
    out = dict(meta)
    cfg = out.get("config")
    if isinstance(cfg, Mapping):
        cfg = dict(cfg)
        for k in ("grid", "points"):
            if k in cfg and not (isinstance(cfg[k], Mapping) and "sha256" in cfg[k]):
                cfg[k] = {"digest": designs_digest(cfg[k])}
        out["config"] = cfg
    return out


def _same_designs(old: Any, new: Any) -> bool:
    """Whether a file's recorded ``grid`` / ``points`` (possibly a part's digest) is ``new``."""
    if isinstance(old, Mapping) and set(old) == {"digest"}:
        return new is not None and old["digest"] == designs_digest(new)
    return old == new


class PartWriter:
    """Buffers rows and writes them as atomic part files ``part-NNNNNN.parquet`` (with the run's
    provenance, its designs as a digest: :func:`part_meta`)."""

    def __init__(self, parts: Path, meta: dict[str, Any], chunk_size: int, flush_interval_s: float) -> None:
        self.parts = parts
        self.meta = part_meta(meta)
        self.chunk_size = max(1, int(chunk_size))
        self.flush_interval_s = flush_interval_s
        self.buffer: list[dict[str, Any]] = []
        try:  # every name taken, whatever it is (a new part never lands on a name already there)
            names = os.listdir(parts)
        except OSError:
            names = []
        existing = [int(m.group(1)) for n in names if (m := PART_NAME.fullmatch(n))]
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
    files = ([output] if output.is_file() else []) + part_files(parts)
    schema = res.result_schema()
    tables = []
    for f in files:
        try:
            t = res.read_table(f)
        except res.ResultsFileError as e:
            raise SweepInputError(str(e)) from None
        t = t.replace_schema_metadata(None)
        # tolerate files written with an older column set: add the missing columns as nulls
        for fld in schema:
            if fld.name not in t.column_names:
                t = t.append_column(fld, pa.nulls(len(t), type=fld.type))
        tables.append(t.select(schema.names).cast(schema))
    if tables:
        df = pa.concat_tables(tables).to_pandas(types_mapper=res.pandas_types_mapper(), use_threads=res.ARROW_THREADS)
    else:
        df = res.rows_to_table([]).to_pandas(types_mapper=res.pandas_types_mapper(), use_threads=res.ARROW_THREADS)
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
    full_meta.update(n_rows=int(len(df)), status_counts=counts, consolidated_utc=now_utc())
    table = pa.Table.from_pandas(df, schema=schema, preserve_index=False, nthreads=None if res.ARROW_THREADS else 1)
    res.write_table_atomic(res._with_metadata(table, full_meta), output)
    for f in files:  # only the parts merged here (never a part that appeared meanwhile)
        if f != output:
            remove_own(f)
    remove_working_files(parts)
    return counts


def remove_working_files(parts: Path) -> None:
    """Remove what a sweep left in its parts folder apart from part files (the ``running/``
    markers, the temporary files of a killed run), and the folder once it is empty: only regular
    files with the sweep's own names, never through a link (:mod:`snapjump_cli.files`)."""
    remove_own_folder(parts / "running", MARKER_NAME)
    remove_own_folder(parts, PART_TMP_NAME)

