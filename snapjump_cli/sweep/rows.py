"""The result-row contract: one row per design, its columns, their types and how a solver result
becomes a row.

Everything about a row lives here: the statuses, the input columns, the solver's metric keys
(:data:`RESULT_KEYS`, declared with their types by :mod:`snapjump_cli.schema`), the per-row provenance columns, the arrow schema, and
:func:`fill_row`, which validates a solver result (type and range of every metric) before a row is
``ok``. :mod:`snapjump_cli.sweep.results` reads and writes tables of these rows.

Columns (in order):

* ``key`` (stable design hash, :func:`snapjump_cli.sweep.storage.design_key`), ``index`` (position in the
  grid or point list), ``status`` (one of :data:`STATUSES`), ``error`` (the cause, empty when ok);
* the inputs :data:`INPUT_COLUMNS` (angles in degrees, SI units otherwise);
* the mesh settings ``mesh_order``, ``mesh_nt``, ``mesh_aspect``;
* the geometry ``R_o`` and ``Delta`` [m] (null when the design is invalid);
* every solver metric under the names of :data:`RESULT_KEYS`;
* ``t_total_s`` (worker wall clock, meshing + solving) and the provenance of the row
  (:data:`PROVENANCE_COLUMNS`: host, pid, finish time, code version and commit, solver settings).
"""
from __future__ import annotations

import json
import math
import numbers
from typing import TYPE_CHECKING, Any, Mapping

from snapjump_cli import schema

if TYPE_CHECKING:
    import pyarrow as pa

__all__ = [
    "STATUSES",
    "INPUT_COLUMNS",
    "MESH_COLUMNS",
    "RESULT_KEYS",
    "BOOL_RESULT_KEYS",
    "STR_RESULT_KEYS",
    "INT_RESULT_KEYS",
    "OPTIONAL_FLOAT_KEYS",
    "ASYM_KEYS",
    "FOLLOW_ROW_KEYS",
    "AIR_KEYS",
    "FLOAT_RESULT_KEYS",
    "PROVENANCE_COLUMNS",
    "SETTINGS_COLUMNS",
    "ROW_CHECK_ERRORS",
    "result_schema",
    "fill_row",
    "settings_json",
]

#: Row status values.
STATUSES: tuple[str, ...] = ("ok", "no_snap", "invalid_geometry", "failed")
#: Design inputs stored per row (names of :class:`snapjump_cli.geometry.caps.Design` fields).
INPUT_COLUMNS: tuple[str, ...] = (
    "eta_i", "theta_i_deg", "eta_o", "theta_o_deg", "mu_ratio",
    "R_i", "mu_i", "J_m", "t_ring_frac", "w_ring_frac",
)
#: Mesh settings stored per row.
MESH_COLUMNS: tuple[str, ...] = ("mesh_order", "mesh_nt", "mesh_aspect")

#: The stable result keys (``snapjump curve --format json`` and one sweep row each): the column
#: keys of every stage of :mod:`snapjump_cli.schema`, in the row's order.
RESULT_KEYS: tuple[str, ...] = tuple(k.name for group in schema.STAGES.values() for k in group if k.column)
_column_keys = tuple(k for group in schema.STAGES.values() for k in group if k.column)
BOOL_RESULT_KEYS: frozenset[str] = frozenset(k.name for k in _column_keys if k.type == "bool")
STR_RESULT_KEYS: frozenset[str] = frozenset(k.name for k in _column_keys if k.type == "str")
INT_RESULT_KEYS: frozenset[str] = frozenset(k.name for k in _column_keys if k.type == "int")
#: Float metrics that may be null in an ok row (set only after a mesh-sensitivity re-solve, or only
#: by the harmonic check, ``solver.harmonics > 0``, and then only when a harmonic lost stability,
#: or only under air).
OPTIONAL_FLOAT_KEYS: frozenset[str] = frozenset(k.name for k in _column_keys if k.optional)
#: The columns of the harmonic check (all null when it is off), the followed branch
#: (``solver.follow``) and air (``fluid: air``): :data:`snapjump_cli.schema.HARMONIC_CHECK`,
#: :data:`~snapjump_cli.schema.FOLLOWED`, :data:`~snapjump_cli.schema.AIR`.
ASYM_KEYS: tuple[str, ...] = schema.columns(schema.HARMONIC_CHECK)
FOLLOW_ROW_KEYS: tuple[str, ...] = schema.columns(schema.FOLLOWED)
AIR_KEYS: tuple[str, ...] = schema.columns(schema.AIR)
#: Every other result key is a float metric.
FLOAT_RESULT_KEYS: tuple[str, ...] = tuple(
    k for k in RESULT_KEYS if k not in BOOL_RESULT_KEYS | STR_RESULT_KEYS | INT_RESULT_KEYS
)
#: Per-row provenance: where and when the row was computed, by which code, with which solver settings.
PROVENANCE_COLUMNS: tuple[str, ...] = ("host", "pid", "finished_utc", "snapjump_version", "git_commit",
                                       "solver_settings")
#: The columns that must agree between rows computed "the same way" (see :mod:`snapjump_cli.jump.rank`).
SETTINGS_COLUMNS: tuple[str, ...] = (*MESH_COLUMNS, "solver_settings", "R_i", "mu_i", "J_m", "t_ring_frac",
                                     "w_ring_frac")

#: How the ``error`` of a row failed by the row check of :func:`fill_row` begins (then ``: `` and the
#: keys or values at fault); a row that failed in the solver starts with the exception's type
#: instead (``Type: message``).
ROW_CHECK_ERRORS: dict[str, str] = {
    "missing": "solver result lacks keys",
    "type": "solver result has values of the wrong type",
    "snaps": "solver result has snaps=None",
    "non_finite": "non-finite metrics in a snapping result",
    "range": "metrics out of range in a snapping result",
}

#: Ranges an ``ok`` row must satisfy (the jump model needs them): key -> (test, wording).
_OK_RANGES: dict[str, tuple[Any, str]] = {
    "dE_J": (lambda x: x > 0, "> 0"),
    "dE_norm": (lambda x: x > 0, "> 0"),
    "dE_energy_J": (lambda x: x > 0, "> 0"),
    "dy_pole_m": (lambda x: x > 0, "> 0"),
    "V_star_m3": (lambda x: x > 0, "> 0"),
    "h_imp_m": (lambda x: x >= 0, ">= 0"),
    "V_inner_solid_m3": (lambda x: x > 0, "> 0"),
    "V_outer_solid_m3": (lambda x: x > 0, "> 0"),
    "wall_s": (lambda x: x >= 0, ">= 0"),
    **{k: (lambda x: x >= 0, ">= 0") for k in INT_RESULT_KEYS},
}


def _arrow_type(key: str) -> "pa.DataType":
    import pyarrow as pa

    if key in BOOL_RESULT_KEYS:
        return pa.bool_()
    if key in STR_RESULT_KEYS:
        return pa.string()
    if key in INT_RESULT_KEYS:
        return pa.int64()
    return pa.float64()


def result_schema() -> "pa.Schema":
    """The arrow schema of a sweep result table (without metadata)."""
    import pyarrow as pa

    fields = [
        pa.field("key", pa.string(), nullable=False),
        pa.field("index", pa.int64()),
        pa.field("status", pa.string(), nullable=False),
        pa.field("error", pa.string()),
    ]
    fields += [pa.field(c, pa.float64()) for c in INPUT_COLUMNS]
    fields += [pa.field("mesh_order", pa.int64()), pa.field("mesh_nt", pa.int64()), pa.field("mesh_aspect", pa.float64())]
    fields += [pa.field("R_o", pa.float64()), pa.field("Delta", pa.float64())]
    fields += [pa.field(k, _arrow_type(k)) for k in RESULT_KEYS]
    fields += [
        pa.field("t_total_s", pa.float64()),
        pa.field("host", pa.string()),
        pa.field("pid", pa.int64()),
        pa.field("finished_utc", pa.string()),
        pa.field("snapjump_version", pa.string()),
        pa.field("git_commit", pa.string()),
        pa.field("solver_settings", pa.string()),
    ]
    return pa.schema(fields)


def settings_json(solver_settings: Mapping[str, Any]) -> str:
    """The solver settings of a row as canonical JSON (sorted keys), comparable between rows."""
    return json.dumps(dict(solver_settings), sort_keys=True, separators=(",", ":"))


class _BadValue(ValueError):
    pass


def _coerce(key: str, v: Any) -> Any:
    """The value of metric ``key`` in its column type; ``None`` stays ``None``.

    Strict: a flag must be a boolean (``bool`` or numpy bool), a count an integral number, a float
    metric a real number; anything else (a string, NaN for a flag or a count) raises ``_BadValue``.
    """
    if v is None:
        return None
    if key in BOOL_RESULT_KEYS:
        if isinstance(v, bool) or type(v).__name__ == "bool_":
            return bool(v)
        raise _BadValue
    if key in STR_RESULT_KEYS:
        if isinstance(v, str):
            return v
        raise _BadValue
    if isinstance(v, bool) or not isinstance(v, numbers.Real):
        raise _BadValue
    if key in INT_RESULT_KEYS:
        x = float(v)
        if not math.isfinite(x) or not x.is_integer():
            raise _BadValue
        return int(x)
    return float(v)


def fill_row(row: dict[str, Any], result: Any) -> None:
    """Fill ``row`` from a solver result and decide ``ok`` / ``no_snap`` / ``failed``.

    A row is ``ok`` only if the result has every key of :data:`RESULT_KEYS`, every value has its
    column's type, ``snaps`` is true, every float metric is finite (except the optional ones and,
    for a lower state off the path, the path integral) and the metrics the jump model needs are in
    range (dE > 0, dy_pole > 0, ...). Otherwise the row is ``failed`` and ``error`` says why.
    Non-finite floats are never stored (null instead).
    """
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
            except (_BadValue, TypeError, ValueError, OverflowError):
                bad_type.append(f"{k}={result[k]!r}")
                values[k] = None
    nonfinite = [k for k in FLOAT_RESULT_KEYS if values.get(k) is not None and not math.isfinite(values[k])]
    absent = [k for k in FLOAT_RESULT_KEYS if k in result and values.get(k) is None and f"{k}=" not in " ".join(bad_type)]
    absent = [k for k in absent if k not in OPTIONAL_FLOAT_KEYS]
    if values.get("lower_state_method") == "descent":
        # a lower state found off the traced path: no path integral
        absent = [k for k in absent if k not in ("dE_path_J", "dE_rel_diff")]
    snaps = values.get("snaps")
    status, error = ("ok" if snaps else "no_snap"), ""
    if missing:
        status, error = "failed", ROW_CHECK_ERRORS["missing"] + ": " + ", ".join(missing)
    elif bad_type:
        status, error = "failed", ROW_CHECK_ERRORS["type"] + ": " + ", ".join(bad_type)
    elif snaps is None:
        status, error = "failed", ROW_CHECK_ERRORS["snaps"] + " (expected true or false)"
    elif status == "ok" and (nonfinite or absent):
        status = "failed"
        error = ROW_CHECK_ERRORS["non_finite"] + ": " + ", ".join(
            [f"{k}={values[k]}" for k in nonfinite] + [f"{k}=None" for k in absent])
    elif status == "ok":
        out_of_range = [f"{k}={values[k]!r} (expected {what})" for k, (good, what) in _OK_RANGES.items()
                        if values.get(k) is not None and not good(values[k])]
        if out_of_range:
            status, error = "failed", ROW_CHECK_ERRORS["range"] + ": " + ", ".join(out_of_range)
    for k in nonfinite:  # never store inf; NaN only as null
        values[k] = None
    row.update(values)
    row.update(status=status, error=error)


def ok_row_problems(metrics: Mapping[str, Any], required: tuple[str, ...] = ()) -> dict[str, Any]:
    """Check the metrics of rows read back as ``ok`` against the row contract's ranges (a file
    edited by hand, or written by other code, may hold anything).

    Parameters
    ----------
    metrics
        Metric name -> numpy array of float values (NaN for null), one entry per row; the names
        absent from it are not checked.
    required
        Metrics that must be present (not null) in an ``ok`` row; a null elsewhere is not checked.

    Returns
    -------
    dict
        Metric name -> boolean array, true where the value breaks the contract (out of range,
        infinite, or null where it is required), for the metrics with at least one such row.
    """
    import numpy as np

    out: dict[str, Any] = {}
    for k, x in metrics.items():
        x = np.asarray(x, dtype=float)
        good = _OK_RANGES[k][0] if k in _OK_RANGES else (lambda v: np.ones(v.shape, bool))
        with np.errstate(invalid="ignore"):
            bad = np.isinf(x) | (np.isfinite(x) & ~good(x))
        if k in required:
            bad |= np.isnan(x)
        if bad.any():
            out[k] = bad
    return out


def ok_range_wording(key: str) -> str:
    """The range an ``ok`` row's metric ``key`` must lie in (e.g. ``"> 0"``), or ``"finite"``."""
    return _OK_RANGES[key][1] if key in _OK_RANGES else "finite"
