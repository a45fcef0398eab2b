"""Apply the mass-spring jump model (docs/physics.md section 6) to sweep results and rank
the designs.

Per row:

* ``ok``: masses ``m_i, m_o = rho * (V_inner_solid_m3, V_outer_solid_m3)``, then
  :func:`snapjump_cli.jump.jump_height` with ``dE_J``, ``dy_pole_m`` and ``h_imp_m``; an ``ok`` row
  whose metrics break the row contract (:func:`snapjump_cli.sweep.rows.ok_row_problems`: a file edited by
  hand) is left unranked, its reason naming the values;
* ``no_snap``: ``y_jump_m = 0``, ``jumped = False``, reason ``"no snap"``;
* ``invalid_geometry`` / ``failed``: ``y_jump_m`` is NaN and the reason repeats the status and error.

Added columns: :data:`RANK_COLUMNS`. The table is sorted by ``y_jump_m`` (descending, NaN last) and
``rank`` numbers the rows that have a jump height (1 = highest).
"""
from __future__ import annotations

import logging
import math
from typing import Any, Callable

import numpy as np
import pandas as pd

from snapjump_cli.settings import JUMP_RHO

__all__ = ["RANK_COLUMNS", "REQUIRED_COLUMNS", "RankInputError", "check_types", "rank_results", "settings_mix",
           "top_frame", "top_table", "TOP_COLUMNS"]

log = logging.getLogger(__name__)

#: Columns added by :func:`rank_results`.
RANK_COLUMNS: tuple[str, ...] = (
    "rank", "y_jump_m", "y_jump_norm", "jump_rise_m", "t_peak_s", "n_contacts", "jumped", "lift_off",
    "jump_complete", "jump_reason", "m_i_kg", "m_o_kg", "k_s",
)
#: Columns a result file must have to be ranked.
REQUIRED_COLUMNS: tuple[str, ...] = (
    "status", "dE_J", "dy_pole_m", "h_imp_m", "V_inner_solid_m3", "V_outer_solid_m3", "R_i",
)


class RankInputError(ValueError):
    """The table cannot be ranked (e.g. required columns are missing)."""


def _finite(x: Any) -> bool:
    try:
        return x is not None and x is not pd.NA and math.isfinite(float(x))
    except (TypeError, ValueError):
        return False


def check_types(df: pd.DataFrame) -> None:
    """Raise :class:`RankInputError` naming the first required column whose type is wrong
    (``status`` text, the metrics numbers)."""
    from pandas.api import types as pt

    for c in REQUIRED_COLUMNS:
        col = df[c]
        if c == "status":
            good = pt.is_string_dtype(col) or (pt.is_object_dtype(col) and col.map(lambda v: isinstance(v, str)).all())
            expected = "text"
        else:
            good = pt.is_numeric_dtype(col) and not pt.is_bool_dtype(col)
            expected = "numbers"
        if not good:
            raise RankInputError(f"column {c!r} has type {col.dtype}, expected {expected}")


def settings_mix(df: pd.DataFrame) -> list[str]:
    """How a result table mixes rows computed differently: one entry per column of
    :data:`snapjump_cli.sweep.rows.SETTINGS_COLUMNS` (plus code version and commit) that takes more than
    one value, e.g. ``"mesh_nt: 2 (4800 rows), 3 (80 rows)"``; empty if the rows agree."""
    from snapjump_cli.sweep.rows import SETTINGS_COLUMNS

    out = []
    for c in (*SETTINGS_COLUMNS, "snapjump_version", "git_commit"):
        if c not in df.columns:
            continue
        counts = df[c].dropna().value_counts()
        if len(counts) > 1:
            out.append(f"{c}: " + ", ".join(f"{v} ({n} rows)" for v, n in counts.items()))
    return out


def rank_results(
    df: pd.DataFrame,
    params: Any | None = None,
    jump_fn: Callable[..., Any] | None = None,
    masses_fn: Callable[..., tuple[float, float]] | None = None,
    exclude_asymmetric: bool = False,
) -> pd.DataFrame:
    """Compute the jump height of every row and sort by it.

    Parameters
    ----------
    df
        A sweep result table (:func:`snapjump_cli.sweep.results.read_results`).
    params
        :class:`snapjump_cli.jump.JumpParams` (default: ``JumpParams()``; ``rho`` sets the masses).
    jump_fn, masses_fn
        Replacements for :func:`snapjump_cli.jump.jump_height` and :func:`snapjump_cli.jump.masses`
        (tests). Without ``jump_fn`` the designs are simulated together
        (:func:`snapjump_cli.jump.jump_heights`: the same results, faster).
    exclude_asymmetric
        Leave unranked the rows whose harmonic check (``solver: {harmonics: N}``) found a
        non-axisymmetric mode losing stability before V* (``asym_first``): their axisymmetric snap
        does not happen. ``y_jump_m`` is NaN and ``jump_reason`` says which harmonic. Without it
        those rows are ranked and the ``asym`` column of the table flags them. Rows whose branch
        was followed (``followed``, ``solver: {follow: true}``) are ranked by the followed snap, which
        happens, and never excluded; their jump with the axisymmetric answer is in ``y_jump_axisym_m``.

    Returns
    -------
    pandas.DataFrame
        A copy of ``df`` with :data:`RANK_COLUMNS`, sorted by ``y_jump_m`` (NaN last).

    Raises
    ------
    RankInputError
        If a column of :data:`REQUIRED_COLUMNS` is missing or has the wrong type.
    """
    missing = [c for c in REQUIRED_COLUMNS if c not in df.columns]
    if missing:
        raise RankInputError("not a sweep result table: missing column(s) " + ", ".join(missing))
    check_types(df)
    jumps_fn = None
    if params is None or jump_fn is None or masses_fn is None:
        from snapjump_cli import jump

        params = params if params is not None else jump.JumpParams()
        if jump_fn is None:
            jumps_fn = jump.jump_heights
        masses_fn = masses_fn or jump.masses
    rho = float(getattr(params, "rho", JUMP_RHO))
    out = _jump_columns(df, params, jump_fn, masses_fn, rho, jumps_fn, _contract_breaches(df))
    followed = (df["followed"].astype("boolean").fillna(False).to_numpy(bool) if "followed" in df.columns
                else np.zeros(len(df), bool))
    if exclude_asymmetric and "asym_first" in df.columns:
        n_first = df["asym_n"] if "asym_n" in df.columns else pd.Series(pd.NA, index=df.index)
        # a followed row's answer is the snap of the branch it follows: it happens, keep it
        for j in np.flatnonzero(df["asym_first"].astype("boolean").fillna(False).to_numpy(bool) & ~followed):
            _unranked(out, j, f"excluded: harmonic n = {n_first.iloc[j]} loses stability before V* (asymmetric mode)")
    ranked = _ranked(df, out)
    if followed.any():
        ranked["y_jump_axisym_m"] = _axisym_jumps(ranked, params, jump_fn, masses_fn, rho, jumps_fn)
    return ranked


def _axisym_jumps(ranked: pd.DataFrame, params: Any, jump_fn, masses_fn, rho: float, jumps_fn) -> np.ndarray:
    """The jump of the axisymmetric answer (``axisym_*``) of each followed ``ok`` row (the row's own
    ``y_jump_m`` where it was not followed): the ranking's followed answer beside the one it
    replaced."""
    y = ranked["y_jump_m"].to_numpy(dtype=float).copy()
    fol = ranked["followed"].astype("boolean").fillna(False).to_numpy(bool) & (ranked["status"] == "ok").to_numpy()
    if not fol.any():
        return y
    sub = ranked.loc[fol].copy()
    for k in ("dE_J", "dy_pole_m", "h_imp_m"):
        sub[k] = sub["axisym_" + k]
    cols = _jump_columns(sub, params, jump_fn, masses_fn, rho, jumps_fn)
    y[np.flatnonzero(fol)] = [math.nan if v is None else v for v in cols["y_jump_m"]]
    return y


def _unranked(out: dict[str, list[Any]], j: int, reason: str) -> None:
    """Row ``j`` gets no jump: no height, no flags (it neither jumped nor failed to), ``reason``."""
    for c in ("t_peak_s", "n_contacts", "jumped", "lift_off", "jump_complete", "k_s", "jump_rise_m"):
        out[c][j] = None
    out["y_jump_m"][j] = math.nan
    out["jump_reason"][j] = reason


def _contract_breaches(df: pd.DataFrame) -> dict[int, str]:
    """Positions of the ``ok`` rows whose metrics break the row contract -> the reason (the values
    at fault); logs a warning when there are any."""
    from snapjump_cli.sweep.rows import FLOAT_RESULT_KEYS, INT_RESULT_KEYS, ok_range_wording, ok_row_problems

    ok = (df["status"] == "ok").fillna(False).to_numpy(bool)
    if not ok.any():
        return {}
    rows = np.flatnonzero(ok)
    metrics = {c: pd.to_numeric(df[c], errors="coerce").to_numpy(dtype=float, na_value=np.nan)[rows]
               for c in (*FLOAT_RESULT_KEYS, *INT_RESULT_KEYS) if c in df.columns}
    problems = ok_row_problems(metrics, required=tuple(c for c in REQUIRED_COLUMNS if c not in ("status", "R_i")))
    out: dict[int, str] = {}
    for k, bad in problems.items():
        for i in np.flatnonzero(bad):
            j = int(rows[i])
            what = f"{k}={metrics[k][i]:g} (expected {ok_range_wording(k)})"
            out[j] = f"{out[j]}, {what}" if j in out else f"invalid ok row: {what}"
    if out:
        j = min(out)
        log.warning("%d ok row(s) break the row contract and are left unranked (e.g. row %d: %s)", len(out),
                    j, out[j].removeprefix("invalid ok row: "))
    return out


def _jump_columns(df: pd.DataFrame, params: Any, jump_fn: Callable[..., Any] | None,
                  masses_fn: Callable[..., tuple[float, float]], rho: float,
                  jumps_fn: Callable[..., list[Any]] | None = None,
                  invalid: dict[int, str] | None = None) -> dict[str, list[Any]]:
    """The added columns (all of :data:`RANK_COLUMNS` but ``rank``), one value per row of ``df``
    (``None`` where there is none). The jump model runs on the ``ok`` rows with ``jumps_fn``
    (all at once) if given, else with ``jump_fn`` row by row; ``invalid`` (position -> reason)
    are ``ok`` rows left unranked."""
    invalid = invalid or {}
    n = len(df)
    out: dict[str, list[Any]] = {c: [None] * n for c in RANK_COLUMNS if c != "rank"}
    ok_rows: list[tuple[int, dict]] = []
    # only the columns read here: boxing every column of every row took longer than the rest
    used = [c for c in (*REQUIRED_COLUMNS, "error") if c in df.columns]
    for j, r in enumerate(df[used].to_dict("records")):
        status, err = r["status"], r.get("error")
        vi, vo = r.get("V_inner_solid_m3"), r.get("V_outer_solid_m3")
        if _finite(vi) and _finite(vo) and float(vi) > 0 and float(vo) > 0:
            try:
                out["m_i_kg"][j], out["m_o_kg"][j] = masses_fn(float(vi), float(vo), rho)
            except (ValueError, TypeError):
                pass
        if status == "ok" and j in invalid:
            _unranked(out, j, invalid[j])
        elif status == "ok":
            ok_rows.append((j, r))
        elif status == "no_snap":
            _no_snap_row(out, j)
        else:
            out["y_jump_m"][j] = math.nan
            text = "" if err is None or err is pd.NA else str(err)
            out["jump_reason"][j] = f"{status}: {text}" if text else str(status)
    n_failed_model = 0
    for (j, r), jr in zip(ok_rows, _jump_results(out, ok_rows, params, jump_fn, jumps_fn)):
        if not _jump_row(out, j, r, jr):
            n_failed_model += 1
    if n_failed_model:
        log.warning("the jump model failed on %d ok row(s); their y_jump_m is NaN", n_failed_model)
    return out


def _jump_results(out: dict[str, list[Any]], rows: list[tuple[int, dict]], params: Any,
                  jump_fn: Callable[..., Any] | None, jumps_fn: Callable[..., list[Any]] | None) -> list[Any]:
    """Per row ``(j, r)`` (status ``ok``, its masses already in ``out``): the jump model's result
    or the exception it raised (one bad row never stops the ranking)."""
    results: list[Any] = [None] * len(rows)
    args: list[tuple[int, tuple]] = []
    for i, (j, r) in enumerate(rows):
        try:
            if out["m_i_kg"][j] is None:
                vi, vo = r.get("V_inner_solid_m3"), r.get("V_outer_solid_m3")
                raise ValueError(f"no solid volumes (V_inner_solid_m3={vi}, V_outer_solid_m3={vo})")
            args.append((i, (float(r["dE_J"]), float(r["dy_pole_m"]), float(r["h_imp_m"]),
                             out["m_i_kg"][j], out["m_o_kg"][j])))
        except Exception as e:  # noqa: BLE001
            results[i] = e
    if jumps_fn is not None:
        for (i, _), res in zip(args, jumps_fn([a for _, a in args], params)):
            results[i] = res
        return results
    for i, a in args:
        try:
            results[i] = jump_fn(*a, params)
        except Exception as e:  # noqa: BLE001
            results[i] = e
    return results


def _jump_row(out: dict[str, list[Any]], j: int, r: dict, jr: Any) -> bool:
    """Fill row ``j`` (status ``ok``) from the jump model's result ``jr``; ``False`` if the model
    failed on it (``jr`` is the exception: ``y_jump_m`` NaN, the reason says why)."""
    if isinstance(jr, Exception):
        out["jump_reason"][j] = f"jump model failed: {type(jr).__name__}: {jr}"
        out["y_jump_m"][j] = math.nan
        return False
    out["y_jump_m"][j] = float(jr.y_jump_m)
    out["t_peak_s"][j] = float(jr.t_peak_s)
    out["n_contacts"][j] = int(jr.n_contacts)
    out["jumped"][j] = bool(jr.jumped)
    out["lift_off"][j] = bool(getattr(jr, "lift_off", jr.jumped))
    out["jump_complete"][j] = bool(getattr(jr, "complete", True))
    out["jump_reason"][j] = str(jr.reason or "")
    out["k_s"][j] = float(jr.k_s)
    out["jump_rise_m"][j] = float(jr.y_jump_m) - float(r["h_imp_m"])
    return True


def _no_snap_row(out: dict[str, list[Any]], j: int) -> None:
    """Fill row ``j`` of a design that does not snap: no jump, height 0."""
    out["y_jump_m"][j] = 0.0
    out["jump_rise_m"][j] = 0.0
    out["t_peak_s"][j] = 0.0
    out["n_contacts"][j] = 0
    out["jumped"][j] = False
    out["lift_off"][j] = False
    out["jump_complete"][j] = True
    out["k_s"][j] = 0.0
    out["jump_reason"][j] = "no snap"


def _ranked(df: pd.DataFrame, out: dict[str, list[Any]]) -> pd.DataFrame:
    """``df`` with the columns ``out`` (typed) and ``rank``, sorted by ``y_jump_m`` (NaN last,
    ties in the input order)."""
    n = len(df)
    ranked = df.copy()
    for c in ("y_jump_m", "jump_rise_m", "t_peak_s", "m_i_kg", "m_o_kg", "k_s"):
        ranked[c] = pd.array([math.nan if v is None else v for v in out[c]], dtype="float64")
    ranked["y_jump_norm"] = ranked["y_jump_m"] / ranked["R_i"].astype("float64")
    ranked["n_contacts"] = pd.array(out["n_contacts"], dtype="Int64")
    for c in ("jumped", "lift_off", "jump_complete"):
        ranked[c] = pd.array(out[c], dtype="boolean")
    ranked["jump_reason"] = pd.array(out["jump_reason"], dtype="string")
    y = ranked["y_jump_m"].to_numpy(dtype=float)
    order = np.lexsort((np.arange(n), -np.where(np.isnan(y), -np.inf, y)))
    ranked = ranked.iloc[order].reset_index(drop=True)
    has = ranked["y_jump_m"].notna().to_numpy()
    rank = np.full(n, -1, dtype=np.int64)
    rank[has] = np.arange(1, int(has.sum()) + 1)
    ranked.insert(0, "rank", pd.array([int(x) if x > 0 else None for x in rank], dtype="Int64"))
    return ranked


#: Columns of the ranked summary (``rank`` output): column -> (source column, scale to the unit shown).
TOP_COLUMNS: dict[str, tuple[str, float]] = {
    "rank": ("rank", 1.0),
    "eta_i": ("eta_i", 1.0),
    "theta_i": ("theta_i_deg", 1.0),
    "eta_o": ("eta_o", 1.0),
    "theta_o": ("theta_o_deg", 1.0),
    "mu_ratio": ("mu_ratio", 1.0),
    "dE_mJ": ("dE_J", 1e3),
    "dy_pole_mm": ("dy_pole_m", 1e3),
    "h_imp_mm": ("h_imp_m", 1e3),
    "y_jump_mm": ("y_jump_m", 1e3),
    "axisym_y_mm": ("y_jump_axisym_m", 1e3),
    "followed": ("followed", 1.0),
    "jumped": ("jumped", 1.0),
    "jump_complete": ("jump_complete", 1.0),
    "self_crossing": ("self_crossing", 1.0),
    "mesh_sensitive": ("mesh_sensitive", 1.0),
    "asym_n": ("asym_n", 1.0),
    "lower_state": ("lower_state_method", 1.0),
    "status": ("status", 1.0),
    "fluid": ("fluid", 1.0),
}


def top_frame(ranked: pd.DataFrame, n: int = 10) -> pd.DataFrame:
    """The first ``n`` ranked rows with the columns of :data:`TOP_COLUMNS` (lengths in mm, energy
    in mJ; a column missing from ``ranked`` is left out)."""
    head = ranked.head(max(0, int(n)))
    checked = "asym_first" in ranked.columns and bool(ranked["asym_first"].notna().any())
    air = "fluid" in ranked.columns and bool((ranked["fluid"] == "air").any())
    followed = "followed" in ranked.columns and bool(ranked["followed"].notna().any())
    cols = {}
    for name, (src, scale) in TOP_COLUMNS.items():
        if src not in head.columns or (name == "asym_n" and not checked):  # asym_n: only after the check
            continue
        if name in ("followed", "axisym_y_mm") and not followed:  # only when branches were followed
            continue
        if name == "fluid" and not air:  # fluid: only when a row was inflated with air
            continue
        cols[name] = head[src] * scale if scale != 1.0 else head[src]
    return pd.DataFrame(cols).reset_index(drop=True)


def top_table(ranked: pd.DataFrame, n: int = 10) -> str:
    """The first ``n`` ranked rows as a fixed-width text table (lengths in mm, energy in mJ)."""
    table = top_frame(ranked, n)
    if table.empty:
        return "(no rows)"
    fmt = {k: (lambda x: "" if pd.isna(x) else f"{x:.4g}") for k in
           ("eta_i", "theta_i", "eta_o", "theta_o", "mu_ratio")}
    fmt.update({k: (lambda x: "-" if pd.isna(x) else f"{x:.2f}") for k in
                ("dE_mJ", "dy_pole_mm", "h_imp_mm", "y_jump_mm", "axisym_y_mm")})
    fmt.update({k: (lambda x: "-" if pd.isna(x) else ("yes" if x else "no")) for k in
                ("jumped", "jump_complete", "self_crossing", "mesh_sensitive", "followed")})
    fmt["asym_n"] = lambda x: "-" if pd.isna(x) else f"{int(x)}"
    # formatted here, not through to_string's formatters: pandas leaves <NA> of nullable columns as is
    other = lambda x: "-" if pd.isna(x) else str(x)  # noqa: E731
    shown = pd.DataFrame({k: [fmt.get(k, other)(x) for x in table[k]] for k in table.columns})
    return shown.to_string(index=False)
