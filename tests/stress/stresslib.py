"""Helpers of the numerical stress suite (``tests/stress``): design sets, sweeps through the real
sweep machinery (:func:`snapjump_cli.sweep.run.run_sweep`), the row classification checks, the
failure-cause table and the invariance comparisons.

Environment knobs (all optional):

* ``SNAPJUMP_STRESS_DIR``: where the resumable result files go (default ``results/stress``);
* ``SNAPJUMP_STRESS_JOBS``: joblib ``n_jobs`` (default -1, every core);
* ``SNAPJUMP_STRESS_MESH``: ``order,nt,aspect`` (default: the sweep default :class:`MeshSettings`);
* ``SNAPJUMP_STRESS_GRID_SAMPLE``: solve only this many paper-grid designs drawn at random (default:
  the whole grid, 4800);
* ``SNAPJUMP_STRESS_GRID_RESULTS``: check this finished paper-grid sweep (parquet) instead of
  running the grid again;
* ``SNAPJUMP_STRESS_RETRY_FAILED=1``: solve the designs a resumed result file holds as failed again
  (after a solver fix);
* ``SNAPJUMP_STRESS_N``: number of random extended-domain designs (default 1000);
* ``SNAPJUMP_STRESS_INVARIANCE_N``: designs in the invariance sample (default 12);
* ``SNAPJUMP_STRESS_SEED``: seed of every random draw (default 5).
"""
from __future__ import annotations

import dataclasses
import math
import os
import re
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from snapjump_cli.sweep import results as res
from snapjump_cli.sweep.rows import ROW_CHECK_ERRORS
from snapjump_cli.sweep.config import SweepConfig, load_config, parse_config
from snapjump_cli.settings import MeshSettings, SolverSettings

REPO = Path(__file__).resolve().parents[2]
PAPER_GRID = REPO / "configs" / "paper_grid.yaml"
#: The extended domain of issue 5 (degrees for the angles).
EXTENDED = {"theta_i_deg": (40.0, 85.0), "eta_i": (5.0, 30.0), "theta_o_deg": (40.0, 90.0),
            "eta_o": (5.0, 30.0), "mu_ratio": (1.0, 20.0)}
#: Columns that legitimately differ between two identical runs.
TIMING_COLUMNS = {"wall_s", "t_total_s", "host", "pid", "finished_utc"}
#: Failure causes, first match wins: (label, regex on the row's error text).
CAUSES: tuple[tuple[str, str], ...] = (
    ("non-finite/None metric in a snapping result", r"non-finite metrics in a snapping result"),
    ("lower state not found after the volume limit", r"volume limit found .* but no lower state"),
    ("continuation failed before any volume limit", r"no volume limit reached before the continuation failed"),
    ("continuation failed", r"continuation failed"),
    ("worker process died", r"worker process died"),
    ("solver result malformed", r"solver result (lacks|has values)"),
    ("meshing error", r"(?i)gmsh|mesh"),
)


def env_int(name: str, default: int) -> int:
    v = os.environ.get(name, "").strip()
    return int(v) if v else default


def out_dir() -> Path:
    d = Path(os.environ.get("SNAPJUMP_STRESS_DIR", "") or REPO / "results" / "stress")
    d.mkdir(parents=True, exist_ok=True)
    return d


def mesh_settings() -> MeshSettings:
    v = os.environ.get("SNAPJUMP_STRESS_MESH", "").strip()
    if not v:
        return MeshSettings()
    o, nt, a = v.split(",")
    return MeshSettings(order=int(o), nt=int(nt), aspect=float(a))


def points_config(points: list[dict], mesh: MeshSettings | None = None, solver: SolverSettings | None = None,
                  n_jobs: int | None = None, source: str = "<stress points>") -> SweepConfig:
    """A sweep over an explicit list of designs (dicts with ``eta_i, theta_i_deg, eta_o, theta_o_deg,
    mu_ratio``), through the sweep config's ``points:`` (validated like a YAML file)."""
    doc = {"points": [{"eta_i": p["eta_i"], "theta_i": p["theta_i_deg"], "eta_o": p["eta_o"],
                       "theta_o": p["theta_o_deg"], "mu_ratio": p["mu_ratio"]} for p in points],
           "chunk_size": 8}
    cfg = parse_config(doc, source)
    return cfg.replace(mesh=mesh or mesh_settings(), solver=solver or SolverSettings(),
                       n_jobs=env_int("SNAPJUMP_STRESS_JOBS", -1) if n_jobs is None else n_jobs)


def random_extended(n: int, seed: int) -> list[dict]:
    """``n`` designs drawn uniformly over :data:`EXTENDED` (rounded to 4 digits; fixed seed).
    Many violate eq 5 (theta_i >= theta_o or y_2 >= y_3): they must come back as invalid_geometry."""
    rng = np.random.default_rng(seed)
    cols = {k: rng.uniform(lo, hi, n) for k, (lo, hi) in EXTENDED.items()}
    return [{k: round(float(cols[k][i]), 4) for k in EXTENDED} for i in range(n)]


def paper_grid_points(sample: int | None = None, seed: int = 5) -> list[dict]:
    """The paper grid's points (all, or ``sample`` of them drawn without replacement)."""
    cfg = load_config(PAPER_GRID)
    pts = [{"eta_i": p.eta_i, "theta_i_deg": p.theta_i_deg, "eta_o": p.eta_o, "theta_o_deg": p.theta_o_deg,
            "mu_ratio": p.mu_ratio} for p in cfg.designs()]
    if sample is not None and sample < len(pts):
        idx = np.random.default_rng(seed).choice(len(pts), size=sample, replace=False)
        pts = [pts[int(i)] for i in sorted(idx)]
    return pts


def invariance_candidates(n: int, seed: int) -> list[dict]:
    """The named designs B, C, D, then ``n`` valid paper-grid designs drawn at random."""
    from snapjump_cli.geometry.designs import named_designs

    named = named_designs()
    out = [{"eta_i": float(named[k]["eta_i"]), "theta_i_deg": float(named[k]["theta_i"]),
            "eta_o": float(named[k]["eta_o"]), "theta_o_deg": float(named[k]["theta_o"]),
            "mu_ratio": float(named[k]["mu_ratio"])} for k in ("B", "C", "D")]
    pts = [p for p in paper_grid_points(None) if valid(p)]
    idx = np.random.default_rng(seed + 1).choice(len(pts), size=min(n, len(pts)), replace=False)
    return out + [pts[int(i)] for i in sorted(idx)]


def valid(p: dict) -> bool:
    from snapjump_cli.geometry.caps import Design, InvalidDesign

    try:
        Design(**p)
    except InvalidDesign:
        return False
    return True


def sweep(points: list[dict], output: Path, **kw) -> "Any":
    """Run (or resume) the real sweep over ``points``; return the consolidated frame."""
    from snapjump_cli.sweep.run import run_sweep

    cfg = points_config(points, **{k: kw.pop(k) for k in ("mesh", "solver", "n_jobs") if k in kw})
    kw.setdefault("retry_failed", bool(env_int("SNAPJUMP_STRESS_RETRY_FAILED", 0)))
    run_sweep(cfg, output=output, progress=kw.pop("progress", False), **kw)
    return res.read_results(output)


# ---- checks -----------------------------------------------------------------------------------
def cause_of(error: str) -> str:
    for label, rx in CAUSES:
        if re.search(rx, error or ""):
            return label
    return "other"


def normalise(error: str) -> str:
    """The error text with numbers replaced by '#' (groups the same cause across designs)."""
    return re.sub(r"[-+]?\d+(\.\d+)?(e[-+]?\d+)?", "#", error or "")[:300]


def check_rows(df) -> list[str]:
    """Violations of the row contract (issue 5): empty list when every row is fine.

    * status is one of ok / no_snap / invalid_geometry / failed;
    * invalid_geometry and failed rows carry their cause (``error`` non-empty; a failed row's text
      starts with the exception type, ``Type: message``, or with the row check's own wording,
      ``snapjump_cli.sweep.rows.ROW_CHECK_ERRORS``);
    * an ok row snaps and holds no NaN / None / inf in any float metric; no row stores inf.
    """
    bad = []
    for _, r in df.iterrows():
        where = (f"row {r['index']} (eta_i={r['eta_i']}, theta_i={r['theta_i_deg']}, eta_o={r['eta_o']}, "
                 f"theta_o={r['theta_o_deg']}, mu={r['mu_ratio']})")
        st = r["status"]
        err = r["error"] if isinstance(r["error"], str) else ""
        if st not in res.STATUSES:
            bad.append(f"{where}: unknown status {st!r}")
            continue
        if st in ("invalid_geometry", "failed") and not err.strip():
            bad.append(f"{where}: {st} without a cause")
        if st == "failed" and not (re.match(r"^[A-Za-z_][\w.]*: |^worker process died", err)
                                   or err.startswith(tuple(ROW_CHECK_ERRORS.values()))):
            bad.append(f"{where}: failed row's error does not name its cause: {err[:120]!r}")
        for k in res.FLOAT_RESULT_KEYS:
            v = r[k]
            isnull = v is None or v is np.nan or (isinstance(v, float) and math.isnan(v)) or _is_na(v)
            if not isnull and isinstance(v, (float, np.floating)) and math.isinf(v):
                bad.append(f"{where}: {k} = inf stored")
            if st == "ok" and isnull and not may_be_null(k, r):
                bad.append(f"{where}: ok row with {k} = NaN/null")
        if st == "ok" and not bool(r["snaps"]):
            bad.append(f"{where}: ok row with snaps = False")
    return bad


def may_be_null(key: str, row) -> bool:
    """Float metrics an ok row may leave empty (the sweep turns any other None metric of a snapping
    result into ``failed``): the optional keys of :mod:`snapjump_cli.sweep.results` (e.g. the coarse
    values of a re-solved snap) and, for a lower state found by descent (not on the traced path),
    the path integral ``dE_path_J`` and ``dE_rel_diff``."""
    if key in getattr(res, "OPTIONAL_FLOAT_KEYS", frozenset()):
        return True
    return key in ("dE_path_J", "dE_rel_diff") and row.get("lower_state_method") == "descent"


def _is_na(v) -> bool:
    try:
        import pandas as pd

        return bool(pd.isna(v))
    except (TypeError, ValueError):
        return False


def summarize(df, title: str) -> str:
    """Counts by status (ok split by self_crossing), the failure rate among valid designs and the
    failure causes with their (number-normalised) texts, as Markdown."""
    counts = Counter(df["status"])
    ok = df[df["status"] == "ok"]
    n_sc = int(ok["self_crossing"].fillna(False).astype(bool).sum()) if len(ok) else 0
    n_ms = int(ok["mesh_sensitive"].fillna(False).astype(bool).sum()) if len(ok) and "mesh_sensitive" in ok else 0
    n_valid = len(df) - counts.get("invalid_geometry", 0)
    n_fail = counts.get("failed", 0)
    rate = n_fail / n_valid if n_valid else 0.0
    L = [f"### {title}", "",
         f"{len(df)} designs: ok {counts.get('ok', 0)} (of which self_crossing {n_sc}, mesh_sensitive {n_ms}), "
         f"no_snap {counts.get('no_snap', 0)}, invalid_geometry {counts.get('invalid_geometry', 0)}, "
         f"failed {n_fail} — failure rate {100 * rate:.1f}% of the {n_valid} valid designs.", ""]
    if "lower_state_method" in ok:
        m = Counter(ok["lower_state_method"].fillna("?"))
        L.append("ok rows by lower-state method: " + ", ".join(f"{k} {v}" for k, v in m.items()) + "  ")
    if "t_total_s" in df and n_valid:
        t = df[df["status"] != "invalid_geometry"]["t_total_s"].astype(float)
        L.append(f"time per valid design: median {t.median():.2f} s, max {t.max():.1f} s, total {t.sum():.0f} s")
    L.append("")
    failed = df[df["status"] == "failed"]
    if len(failed):
        L += ["| cause | n | error text (numbers as #) | example design |", "|---|---|---|---|"]
        groups: dict[tuple[str, str], list] = {}
        for _, r in failed.iterrows():
            groups.setdefault((cause_of(r["error"]), normalise(r["error"])), []).append(r)
        for (cause, text), rows in sorted(groups.items(), key=lambda kv: -len(kv[1])):
            r = rows[0]
            ex = (f"eta_i={r['eta_i']:.4g} theta_i={r['theta_i_deg']:.4g} eta_o={r['eta_o']:.4g} "
                  f"theta_o={r['theta_o_deg']:.4g} mu={r['mu_ratio']:.4g}")
            L.append(f"| {cause} | {len(rows)} | {text.replace('|', '/')} | {ex} |")
        L.append("")
    inv = df[df["status"] == "invalid_geometry"]
    if len(inv):
        kinds = Counter(re.sub(r"[-+]?\d+(\.\d+)?(e[-+]?\d+)?", "#", e)[:80] for e in inv["error"])
        L.append("invalid_geometry causes: " + "; ".join(f"{k!r} ×{v}" for k, v in kinds.most_common(4)))
        L.append("")
    return "\n".join(L)


# ---- invariance -------------------------------------------------------------------------------
def variant_solvers(base: SolverSettings) -> dict[str, SolverSettings]:
    """The invariance variants of issue 5: initial arc length x0.25 and x4, every Newton tolerance
    (the fields ``tol``, ``tol_path``, ... of :class:`SolverSettings`) / 10."""
    tols = {f.name: getattr(base, f.name) * 0.1 for f in dataclasses.fields(base) if f.name.startswith("tol")}
    return {"ds0 x0.25": dataclasses.replace(base, ds0=base.ds0 * 0.25),
            "ds0 x4": dataclasses.replace(base, ds0=base.ds0 * 4.0),
            "tol /10": dataclasses.replace(base, **tols)}


def compare_dE(base_df, var_df, label: str, rel: float = 0.005) -> tuple[list[str], list[dict]]:
    """dE of every design solved ok in ``base_df`` must match ``var_df`` within ``rel`` (same status,
    too). Returns (violations, per-design records)."""
    bad, recs = [], []
    b = base_df.set_index("index")
    v = var_df.set_index("index")
    for i, rb in b.iterrows():
        rv = v.loc[i]
        rec = {"index": int(i), "variant": label, "base_status": rb["status"], "var_status": rv["status"],
               "dE_base": rb["dE_J"], "dE_var": rv["dE_J"], "rel": None}
        where = (f"{label}: design eta_i={rb['eta_i']:.4g} theta_i={rb['theta_i_deg']:.4g} eta_o={rb['eta_o']:.4g} "
                 f"theta_o={rb['theta_o_deg']:.4g} mu={rb['mu_ratio']:.4g}")
        if rb["status"] in ("ok", "no_snap"):
            if rv["status"] != rb["status"]:
                bad.append(f"{where}: status {rb['status']} -> {rv['status']} ({rv['error'][:200]})")
            elif rb["status"] == "ok":
                rec["rel"] = abs(rv["dE_J"] - rb["dE_J"]) / abs(rb["dE_J"])
                if not rec["rel"] <= rel:
                    bad.append(f"{where}: dE {rb['dE_J']:.6g} -> {rv['dE_J']:.6g} J "
                               f"({100 * rec['rel']:.2f}% > {100 * rel:g}%; lower state "
                               f"{rb['lower_state_method']} -> {rv['lower_state_method']})")
        recs.append(rec)
    return bad, recs


def compare_bitwise(a_df, b_df, common_only: bool = False) -> list[str]:
    """Every non-timing column of two runs with the same settings must be identical (NaN == NaN).
    ``common_only``: compare the designs present in both (else the key sets must match)."""
    bad = []
    a = a_df.set_index("key").sort_index()
    b = b_df.set_index("key").sort_index()
    if common_only:
        common = a.index.intersection(b.index)
        if not len(common):
            return ["the two runs share no design"]
        a, b = a.loc[common], b.loc[common]
    elif list(a.index) != list(b.index):
        return ["the two runs hold different keys"]
    for col in a.columns:
        if col in TIMING_COLUMNS or (common_only and col == "index"):
            continue
        for k in a.index:
            x, y = a.at[k, col], b.at[k, col]
            same = (_is_na(x) and _is_na(y)) or (not _is_na(x) and not _is_na(y) and x == y)
            if not same:
                bad.append(f"design {a.at[k, 'index']}: {col} {x!r} != {y!r}")
    return bad
