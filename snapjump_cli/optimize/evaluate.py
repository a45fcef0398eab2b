"""Evaluations of ``snapjump optimize``: batches of designs solved by
:func:`snapjump_cli.sweep.run.run_sweep` into a cache sweep file (memoised, resumable), their objective,
and the confirmation of the best designs on a finer mesh."""
from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import pandas as pd

from snapjump_cli.sweep.config import DesignPoint
from snapjump_cli.jump import JumpParams
from snapjump_cli.optimize.spec import SIG_DIGITS, COLUMNS, OptimizeSpec, finer_mesh
from snapjump_cli.settings import MeshSettings

log = logging.getLogger("snapjump_cli.optimize.run")


# ---- evaluation ----------------------------------------------------------------------------------
def _round(x: float) -> float:
    return float(f"{float(x):.{SIG_DIGITS}g}")


def objective_values(df: pd.DataFrame, objective: str, params: JumpParams) -> pd.DataFrame:
    """``df`` with ``y_jump_m`` and ``_f`` (the objective, NaN where infeasible), in its order."""
    from snapjump_cli.jump.rank import rank_results

    from snapjump_cli.jump.rank import RANK_COLUMNS

    d = df.drop(columns=[c for c in (*RANK_COLUMNS, "_f") if c in df.columns])
    d = d.reset_index(drop=True).assign(_pos=np.arange(len(d)))
    ranked = rank_results(d, params).sort_values("_pos").reset_index(drop=True)
    ok = (ranked["status"] == "ok").to_numpy(dtype=bool)
    if "mesh_sensitive" in ranked.columns:
        ok &= ~ranked["mesh_sensitive"].fillna(False).astype(bool).to_numpy()
    y = ranked["y_jump_m"].to_numpy(dtype=float)
    f = (y if objective == "y_jump_m" else ranked["dE_J"].to_numpy(dtype=float)).copy()
    ok &= np.isfinite(y) & np.isfinite(f)
    f[~ok] = np.nan
    return ranked.drop(columns="_pos").assign(_f=f)


@dataclass
class Evaluation:
    key: str
    params: tuple[float, ...]   # the five parameters (physical, rounded)
    iteration: int
    stage: str
    number: int                 # evaluation number (order asked)
    valid: bool                 # geometry valid (a solve was needed)
    f: float = math.nan         # objective (NaN: infeasible)
    row: dict | None = None


class Evaluator:
    """Asks run_sweep for batches of designs and keeps every evaluation (memoised by key)."""

    def __init__(self, spec: OptimizeSpec, cache: Path, n_jobs: int, budget: int,
                 solve_fn: Callable | None, warm_up_fn: Callable | None,
                 on_batch: Callable[[int, int, float], None] | None) -> None:
        self.spec = spec
        self.cache = cache
        self.n_jobs = n_jobs
        self.budget = budget
        self.solve_fn = solve_fn
        self.warm_up_fn = warm_up_fn
        self.warmed = False
        self.on_batch = on_batch
        self.evals: list[Evaluation] = []
        self.by_key: dict[str, Evaluation] = {}
        self.points: list[tuple[float, ...]] = []
        self.n_solves = 0
        self.n_batches = 0
        self.n_resumed = 0
        # designs an earlier (longer or interrupted) run left in the cache and not asked (yet):
        # handed to run_sweep as well (already done, never solved) so the cache stays one grid
        self.cached: dict[str, tuple[float, ...]] = _cached_designs(cache, self)
        self.recorded: set[str] = set(self.cached)  # batches made only of these need no sweep

    # parameters <-> keys
    def point(self, params: Sequence[float]) -> DesignPoint:
        c = self.spec.sweep
        ei, ti, eo, to, mr = params
        return DesignPoint(index=0, eta_i=ei, theta_i_deg=ti, eta_o=eo, theta_o_deg=to, mu_ratio=mr, R_i=c.R_i,
                           mu_i=c.mu_i, J_m=c.J_m, t_ring_frac=c.t_ring_frac, w_ring_frac=c.w_ring_frac)

    def key(self, params: Sequence[float], mesh: MeshSettings | None = None) -> str:
        from snapjump_cli.sweep.run import design_key

        return design_key(self.point(params), mesh or self.spec.sweep.mesh, self.spec.sweep.solver)

    def valid(self, params: Sequence[float]) -> bool:
        from snapjump_cli.geometry.caps import Design, InvalidDesign

        try:
            Design(**self.point(params).design_kwargs())
        except InvalidDesign:
            return False
        return True

    @property
    def remaining(self) -> int:
        return self.budget - self.n_solves

    def best(self) -> Evaluation | None:
        feas = [e for e in self.evals if math.isfinite(e.f)]
        return max(feas, key=lambda e: (e.f, -e.number)) if feas else None

    def ask(self, requests: Sequence[tuple[Sequence[float], str]], iteration: int) -> list[Evaluation | None]:
        """Evaluate designs (in priority order); returns one record per request, ``None`` where the
        budget ran out before it. Designs asked before are not solved again."""
        out: list[Evaluation | None] = []
        new: list[Evaluation] = []
        for params, stage in requests:
            params = tuple(_round(x) for x in params)
            k = self.key(params)
            e = self.by_key.get(k)
            if e is None:
                valid = self.valid(params)
                if valid and self.remaining <= 0:
                    out.append(None)
                    continue
                e = Evaluation(key=k, params=params, iteration=iteration, stage=stage, number=len(self.evals), valid=valid)
                self.evals.append(e)
                self.by_key[k] = e
                self.points.append(params)
                self.cached.pop(k, None)
                new.append(e)
                if valid:
                    self.n_solves += 1
            out.append(e)
        if new:
            self._solve(new)
        return out

    def _solve(self, new: list[Evaluation]) -> None:
        from snapjump_cli.sweep.run import run_sweep

        n_solved = 0
        if any(e.key not in self.recorded for e in new):
            cfg = self.spec.sweep.replace(points=tuple(self.points) + tuple(self.cached.values()), output=self.cache)
            warm = self.warm_up_fn if (self.warm_up_fn is not None or not self.warmed) else _no_warm_up
            summary = run_sweep(cfg, output=self.cache, n_jobs=self.n_jobs, progress=False, solve_fn=self.solve_fn,
                                warm_up_fn=warm, **_append_kw())
            n_solved = summary.n_solved
            self.warmed = self.warmed or n_solved > 0
        self.n_resumed += sum(1 for e in new if e.valid) - n_solved
        wanted = {e.key for e in new}
        df = _read_cache(self.cache, wanted)
        scored = objective_values(df, self.spec.objective, self.spec.jump)
        rows = {r["key"]: r for r in scored.to_dict("records")}
        for e in new:
            r = rows.get(e.key)
            if r is None:  # pragma: no cover - run_sweep records every design it is given
                raise RuntimeError(f"design {e.params} was not recorded in {self.cache}")
            e.row = r
            e.f = float(r["_f"]) if r["_f"] is not None and math.isfinite(float(r["_f"])) else math.nan
        self.n_batches += 1
        b = self.best()
        if self.on_batch is not None:
            self.on_batch(self.n_solves, self.budget, b.f if b is not None else math.nan)


def _read_cache(cache: Path, keys: set[str]) -> pd.DataFrame:
    """The rows of ``keys`` in ``cache`` (its file and part files; the newest record wins)."""
    from snapjump_cli.sweep import results as res
    from snapjump_cli.sweep.storage import result_files

    files = result_files(cache)
    frames = [df[df["key"].isin(keys)] for df in (res.read_results(f) for f in files)]
    return pd.concat(frames, ignore_index=True).drop_duplicates(subset="key", keep="last")


def _cached_designs(cache: Path, ev: "Evaluator", mesh: MeshSettings | None = None) -> dict[str, tuple[float, ...]]:
    """key (on ``mesh``, default the spec's) -> the five parameters of every design recorded in
    ``cache`` (file and part files)."""
    from snapjump_cli.sweep import results as res
    from snapjump_cli.sweep.storage import result_files

    files = result_files(cache)
    out: dict[str, tuple[float, ...]] = {}
    for f in files:
        df = res.read_results(f, columns=list(COLUMNS.values()))
        for vals in df.itertuples(index=False):
            p = tuple(float(x) for x in vals)
            out.setdefault(ev.key(p, mesh), p)
    return out


def _append_kw() -> dict[str, bool]:
    """``append=True`` where run_sweep knows it: a batch asks only the designs asked so far, so the
    cache may hold designs of a longer earlier run (a resume); the settings are checked by
    :func:`check_cache` instead."""
    import inspect

    from snapjump_cli.sweep.run import run_sweep

    return {"append": True} if "append" in inspect.signature(run_sweep).parameters else {}



def _no_warm_up() -> None:
    """The kernels are compiled by the first batch; later batches skip the warm-up."""



def confirm(ev: Evaluator, spec: OptimizeSpec, path: Path, n_jobs: int, solve_fn: Callable | None
             ) -> tuple[Evaluation | None, dict | None, list, list[dict]]:
    """Re-solve the best feasible designs on the finer mesh until one holds."""
    from snapjump_cli.sweep.run import run_sweep

    c = spec.confirm
    mesh = finer_mesh(spec.sweep.mesh)
    order = sorted([e for e in ev.evals if math.isfinite(e.f)], key=lambda e: (-e.f, e.number))[:c.candidates]
    batch = max(1, n_jobs if n_jobs > 0 else (os.cpu_count() or 1))
    tried: list = []
    rows: list[dict] = []
    asked: list[tuple[float, ...]] = []
    cached = _cached_designs(path, ev, mesh)
    recorded = set(cached)
    for i in range(0, len(order), batch):
        group = order[i:i + batch]
        asked += [e.params for e in group]
        keys = [ev.key(e.params, mesh) for e in group]
        for k in keys:
            cached.pop(k, None)
        if any(k not in recorded for k in keys):
            cfg = spec.sweep.replace(points=tuple(asked) + tuple(cached.values()), mesh=mesh, output=path)
            run_sweep(cfg, output=path, n_jobs=n_jobs, progress=False, solve_fn=solve_fn,
                      warm_up_fn=_no_warm_up if ev.warmed or solve_fn is not None else None, **_append_kw())
        scored = objective_values(_read_cache(path, set(keys)), spec.objective, spec.jump)
        by_key = {r["key"]: r for r in scored.to_dict("records")}
        for e, k in zip(group, keys):
            r = by_key[k]
            r.update(iteration=e.iteration, stage="confirm")
            rows.append(r)
            f2 = float(r["_f"]) if r["_f"] is not None and math.isfinite(float(r["_f"])) else math.nan
            held = math.isfinite(f2) and abs(f2 - e.f) <= c.tolerance * abs(e.f)
            tried.append((e.params, e.f, f2, held))
            log.info("confirmation of %s: %.6g on the search mesh, %.6g on the finer mesh: %s",
                     e.params, e.f, f2, "holds" if held else "does not hold")
            if held:
                return e, r, tried, rows
    return None, None, tried, rows

