"""Result files: atomic parquet I/O of result tables and their provenance metadata.

One row per design; the columns, their types and the validation of a solver result are the row
contract of :mod:`snapjump_cli.sweep.rows` (re-exported here). Metrics of rows that are not ``ok`` may
be null (read back as NaN / ``pd.NA``); an ``ok`` row never holds a NaN or infinite metric.

Provenance (resolved config, package and dependency versions, git commit) is stored as JSON under
the key ``snapjump`` of the parquet schema metadata; read it with :func:`read_metadata`.
"""
from __future__ import annotations

import json
import logging
import platform
import re
import subprocess
import sys
from datetime import datetime, timezone
from importlib import metadata as importlib_metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterable, Mapping, Sequence

from snapjump_cli.files import write_atomic
from snapjump_cli.sweep.rows import (  # the row contract, re-exported for readers of result files
    BOOL_RESULT_KEYS,
    FLOAT_RESULT_KEYS,
    INPUT_COLUMNS,
    INT_RESULT_KEYS,
    OPTIONAL_FLOAT_KEYS,
    RESULT_KEYS,
    STATUSES,
    STR_RESULT_KEYS,
    result_schema,
)

if TYPE_CHECKING:  # pandas / pyarrow are imported inside the functions: the sweep workers only
    import pandas as pd  # need the column-type constants of this module and stay light
    import pyarrow as pa

__all__ = [
    "STATUSES",
    "INPUT_COLUMNS",
    "METADATA_KEY",
    "ARROW_THREADS",
    "BOOL_RESULT_KEYS",
    "INT_RESULT_KEYS",
    "STR_RESULT_KEYS",
    "FLOAT_RESULT_KEYS",
    "OPTIONAL_FLOAT_KEYS",
    "RESULT_KEYS",
    "result_schema",
    "rows_to_table",
    "write_table_atomic",
    "write_frame_atomic",
    "read_results",
    "read_table",
    "check_columns",
    "ResultsFileError",
    "pandas_types_mapper",
    "read_metadata",
    "provenance",
    "failure_reasons",
    "group_failures",
]

log = logging.getLogger(__name__)

#: Key of the provenance JSON in the parquet schema metadata.
METADATA_KEY = b"snapjump"

#: Whether result files are read and converted with Arrow's thread pool: never. Result files are
#: small (a part holds ``chunk_size`` rows, a grid a few thousand), so the pool saves nothing, and a
#: pool worker still alive when the interpreter exits can abort a finished process with SIGABRT
#: ("terminate called without an active exception", exit code 134) after every row was written.
ARROW_THREADS = False


def _with_metadata(table: pa.Table, meta: Mapping[str, Any] | None) -> pa.Table:
    if meta is None:
        return table
    md = dict(table.schema.metadata or {})
    md[METADATA_KEY] = json.dumps(meta, sort_keys=True, default=str).encode()
    return table.replace_schema_metadata(md)


def rows_to_table(rows: Iterable[Mapping[str, Any]], meta: Mapping[str, Any] | None = None) -> pa.Table:
    """Convert row dicts (missing keys -> null) to a table with :func:`result_schema`.

    Parameters
    ----------
    rows
        One mapping per design; unknown keys are ignored.
    meta
        Provenance stored under :data:`METADATA_KEY` in the schema metadata.
    """
    import pandas as pd
    import pyarrow as pa

    schema = result_schema()
    cols = {f.name: [] for f in schema}
    for r in rows:
        for name in cols:
            v = r.get(name)
            if v is not None and v is pd.NA:
                v = None
            cols[name].append(v)
    arrays = [pa.array(cols[f.name], type=f.type) for f in schema]
    return _with_metadata(pa.Table.from_arrays(arrays, schema=schema), meta)


def write_table_atomic(table: pa.Table, path: str | Path) -> Path:
    """Write a parquet file atomically (:func:`snapjump_cli.files.write_atomic`: a temporary file
    in the target's folder, then a rename; links followed, devices and FIFOs refused).

    A reader (or a resumed sweep) therefore sees either the complete file or none.
    """
    import pyarrow.parquet as pq

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:  # a file object: pyarrow takes no file name that is not valid UTF-8
            pq.write_table(table, fh)

    return write_atomic(path, write)


def write_frame_atomic(df: pd.DataFrame, path: str | Path, meta: Mapping[str, Any] | None = None) -> Path:
    """Write a DataFrame to parquet atomically, with provenance ``meta`` in the schema metadata."""
    import pyarrow as pa

    table = pa.Table.from_pandas(df, preserve_index=False, nthreads=None if ARROW_THREADS else 1)
    return write_table_atomic(_with_metadata(table, meta), path)


def pandas_types_mapper() -> Callable[[Any], Any]:
    """``types_mapper`` for ``pyarrow.Table.to_pandas``: nullable Int64, boolean and string dtypes."""
    import pandas as pd
    import pyarrow as pa

    mapping = {pa.int64(): pd.Int64Dtype(), pa.bool_(): pd.BooleanDtype(), pa.string(): pd.StringDtype()}
    return mapping.get


class ResultsFileError(ValueError):
    """A results file (or part file) that cannot be used: one line naming the file, the column or
    the value, and what to do."""


_PARQUET_MAGIC = b"PAR1"


def _type_words(t: Any) -> str:
    import pyarrow as pa

    if pa.types.is_floating(t):
        return "numbers"
    if pa.types.is_integer(t):
        return "integers"
    if pa.types.is_boolean(t):
        return "true/false"
    if pa.types.is_string(t) or pa.types.is_large_string(t):
        return "text"
    return str(t)


def _compatible(got: Any, want: Any) -> bool:
    """Whether a column of type ``got`` is read as ``want`` without changing a value (nulls, wider
    integers or floats, integers as floats)."""
    import pyarrow as pa

    if got == want or pa.types.is_null(got):
        return True
    if pa.types.is_floating(want):
        return pa.types.is_floating(got) or pa.types.is_integer(got)
    if pa.types.is_integer(want):
        return pa.types.is_integer(got)
    if pa.types.is_string(want):
        return pa.types.is_large_string(got)
    return False


def check_columns(table: pa.Table, path: str | Path) -> pa.Table:
    """``table`` with the columns of the row contract (:func:`result_schema`) it holds cast to
    their types; a column of another kind (text where numbers belong, ...) is refused.

    Raises
    ------
    ResultsFileError
        Naming the file, the column, its type and the expected one.
    """
    schema = result_schema()
    for f in schema:
        if f.name not in table.column_names:
            continue
        got = table.schema.field(f.name).type
        if not _compatible(got, f.type):
            raise ResultsFileError(
                f"{path}: column {f.name!r} has type {got}, expected {_type_words(f.type)} ({f.type}); the file was "
                f"not written by snapjump or was edited: run the sweep again, or correct that column")
        if got != f.type:
            i = table.schema.get_field_index(f.name)
            table = table.set_column(i, f.name, table.column(i).cast(f.type))
    return table


def _looks_like_csv(path: str | Path) -> bool:
    """Whether the file starts with a line of text holding commas or tabs (a CSV header)."""
    try:
        with open(path, "rb") as fh:
            first = fh.read(4096).split(b"\n", 1)[0]
    except OSError:
        return False
    return bool(first) and (b"," in first or b"\t" in first) and all(32 <= b < 127 or b in b"\t\r" for b in first)


def read_table(path: str | Path, columns: list[str] | None = None) -> pa.Table:
    """Read a result, part or ranked parquet file: the one reader of result files.

    The path must be a regular file (never a FIFO or a device: they would block), a parquet file
    (a CSV is named as such), and its columns of the row contract of their kinds
    (:func:`check_columns`).

    Raises
    ------
    ResultsFileError
        One line naming the file and what to do.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    from snapjump_cli.files import check_readable

    check_readable(path, ResultsFileError, "a parquet file")
    try:
        with open(path, "rb") as fh:
            head = fh.read(4)
    except OSError as e:
        raise ResultsFileError(f"{path}: cannot read it ({e.strerror})") from None
    if head != _PARQUET_MAGIC:
        if str(path).lower().endswith((".csv", ".tsv", ".txt")) or _looks_like_csv(path):
            raise ResultsFileError(
                f"{path}: is a text (CSV) file; snapjump reads results as the parquet file a sweep writes "
                f"(snapjump sweep GRID.yaml -o RESULTS.parquet); a CSV of designs goes into a sweep config as "
                f"`points: FILE.csv`")
        raise ResultsFileError(f"{path}: not a readable parquet file (it does not start as one); expected the "
                               f"results of snapjump sweep")
    try:  # through a Python file object: pyarrow takes no file name that is not valid UTF-8
        with open(path, "rb") as fh:  # no Arrow thread pool: see ARROW_THREADS
            table = pq.read_table(fh, columns=columns, use_threads=ARROW_THREADS)
    except (pa.ArrowException, OSError, KeyError, ValueError) as e:
        why = " ".join(str(e).split()) or type(e).__name__
        raise ResultsFileError(f"{path}: not a readable parquet file ({why[:300]})") from None
    return check_columns(table, path)


def read_results(path: str | Path, columns: list[str] | None = None) -> pd.DataFrame:
    """Read a result (or ranked) parquet file into pandas with nullable dtypes (:func:`read_table`:
    a bad file raises :class:`ResultsFileError`).

    Integers become ``Int64``, booleans ``boolean``, strings ``string`` (nulls are ``pd.NA``);
    floats stay ``float64`` with NaN for missing values.
    """
    table = read_table(path, columns=columns)
    return table.to_pandas(types_mapper=pandas_types_mapper(), use_threads=ARROW_THREADS)


def read_metadata(path: str | Path) -> dict[str, Any]:
    """The provenance dict stored in a parquet file's schema metadata (``{}`` if none).

    Raises
    ------
    ResultsFileError
        The file is not a readable parquet file, or its provenance is not a JSON mapping.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    from snapjump_cli.files import check_readable

    check_readable(path, ResultsFileError, "a parquet file")
    try:
        with open(path, "rb") as fh:
            md = pq.read_schema(fh).metadata or {}
    except (pa.ArrowException, OSError, ValueError) as e:
        why = " ".join(str(e).split()) or type(e).__name__
        raise ResultsFileError(f"{path}: not a readable parquet file ({why[:300]})") from None
    raw = md.get(METADATA_KEY)
    if not raw:
        return {}
    try:
        meta = json.loads(raw)
    except (ValueError, UnicodeDecodeError) as e:
        raise ResultsFileError(f"{path}: its provenance (parquet metadata key 'snapjump') is not JSON ({e}); the "
                               f"file was edited or damaged: run the sweep again, or drop that metadata key") from None
    if not isinstance(meta, dict):
        raise ResultsFileError(f"{path}: its provenance (parquet metadata key 'snapjump') is not a JSON mapping; "
                               f"run the sweep again, or drop that metadata key")
    return meta


# ---- provenance ---------------------------------------------------------------------------------
_DEPENDENCIES = ("numpy", "scipy", "numba", "gmsh", "pandas", "pyarrow", "joblib", "pyyaml", "click", "tqdm",
                 "dask", "distributed", "matplotlib")


def _dist_version(name: str) -> str | None:
    try:
        return importlib_metadata.version(name)
    except importlib_metadata.PackageNotFoundError:
        return None


def git_commit(path: str | Path | None = None) -> dict[str, Any] | None:
    """The git commit (and whether the tree is dirty) of the checkout holding ``path``.

    Returns ``None`` when git or the repository is unavailable.
    """
    cwd = Path(path) if path is not None else Path(__file__).resolve().parent
    try:
        sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=cwd, capture_output=True, text=True, timeout=5)
        if sha.returncode != 0:
            return None
        st = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=cwd,
                            capture_output=True, text=True, timeout=5)
        return {"commit": sha.stdout.strip(), "dirty": bool(st.stdout.strip()) if st.returncode == 0 else None}
    except (OSError, subprocess.SubprocessError):
        return None


def provenance(config: Mapping[str, Any] | None = None, **extra: Any) -> dict[str, Any]:
    """Provenance of a result file.

    Parameters
    ----------
    config
        The resolved configuration (plain data).
    **extra
        Further entries (e.g. ``command``, ``status_counts``).

    Returns
    -------
    dict
        ``package``, ``version``, ``git`` (commit/dirty or None), ``python``, ``platform``,
        ``dependencies`` (installed versions), ``created_utc``, ``result_keys``, ``config`` and extras.
    """
    from snapjump_cli import __version__

    meta: dict[str, Any] = {
        "package": "snapjump",
        "version": __version__,
        "git": git_commit(),
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "dependencies": {d: v for d in _DEPENDENCIES if (v := _dist_version(d)) is not None},
        "created_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "result_keys": list(RESULT_KEYS),
        "config": dict(config) if config is not None else None,
    }
    meta.update(extra)
    return meta


# ---- why designs were not solved ---------------------------------------------------------------
_VALUE_RE = re.compile(r"(=|<=|>=|<|>|got|step|at|after|of)\s+-?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def _reason(error: Any) -> str:
    """An error message with the values of one design replaced by ``#`` (so alike reasons group)."""
    text = " ".join(error.split()) if isinstance(error, str) else ""
    return _VALUE_RE.sub(lambda m: f"{m.group(1)} #", text)


def group_failures(statuses: Sequence[Any], errors: Sequence[Any],
                   which: tuple[str, ...] = ("invalid_geometry", "failed")) -> list[dict]:
    """The reasons of the rows whose status is one of ``which``, grouped by status and reason (the
    values of one design shown as ``#``): one dict per group, ``status``, ``reason``, ``count`` and
    the first message as ``example``, largest first."""
    groups: dict[tuple[str, str], dict] = {}
    for st, err in zip(statuses, errors):
        if st not in which:
            continue
        text = " ".join(err.split()) if isinstance(err, str) else ""
        key = (str(st), _reason(text) or "(no reason recorded)")
        g = groups.setdefault(key, {"status": key[0], "reason": key[1], "count": 0, "example": text})
        g["count"] += 1
    return sorted(groups.values(), key=lambda g: (-g["count"], g["status"], g["reason"]))


def failure_reasons(df: pd.DataFrame, statuses: tuple[str, ...] = ("invalid_geometry", "failed"),
                    top: int = 5, source: str | Path | None = None) -> list[str]:
    """The reasons of the designs of ``statuses`` (their ``error`` column), grouped
    (:func:`group_failures`): for each status with rows, a line ``<status>: <n> designs``, then up
    to ``top`` lines ``<count> x <reason>``, most frequent first. ``[]`` if there are none."""
    if "status" not in df.columns:
        return []
    errors = df["error"] if "error" in df.columns else [""] * len(df)
    groups = group_failures(df["status"], errors, statuses)
    lines = []
    for st in statuses:
        gs = [g for g in groups if g["status"] == st]
        if not gs:
            continue
        n = sum(g["count"] for g in gs)
        lines.append(f"{st}: {n} design{'s' if n != 1 else ''}, why:")
        lines += [f"  {g['count']} x {g['reason']}" for g in gs[:top]]
        if len(gs) > top:
            where = f" (column 'error' of {source})" if source is not None else " (column 'error')"
            lines.append(f"  ... and {len(gs) - top} other reasons{where}")
    return lines
