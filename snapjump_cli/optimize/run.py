"""Search the continuous design space for the highest jump (``snapjump optimize``).

Spec (YAML, validated like a sweep config: every error is a :class:`~snapjump_cli.sweep.config.ConfigError`
naming the file and the key path; defaults in brackets)::

    bounds:                    # required: all five parameters
      eta_i:    [5, 8]         # [lo, hi] (lo <= hi) or one number (fixed)
      theta_i:  [70, 80]       # deg
      eta_o:    [5, 20]
      theta_o:  [76, 90]       # deg
      mu_ratio: [1, 20]        # or e.g. 5.8 (fixed)
    objective: y_jump_m        # y_jump_m (the mass-spring model) or dE_J
    budget: 300                # number of solves (designs meshed and solved; see below)
    seed: 0                    # integer >= 0: the same seed gives the same designs and answer
    method: pattern            # pattern (multi-start parallel pattern search) or differential_evolution
    search: {starts: 3, init: 2d+1, step: 0.125, min_step: 1/128, spread: 0.2, popsize: 8,
             poll: coordinate, model: true, model_step: 1/16}
    confirm: {tolerance: 0.02, candidates: 5}   # or false (no confirmation solve)
    jump: {rho: 1000, c_d: 0.4, alpha: 0.5}     # snapjump_cli.jump.JumpParams
    R_i, materials, ring, mesh, solver, n_jobs, chunk_size   # as in a sweep config
    output: results/<spec stem>.parquet

Method ``pattern`` (default; docs/optimize.md justifies it): the box is normalised to ``[0, 1]^d``
over the ``d`` free parameters. Start points are the best valid rows of ``--from`` inside the box
(greedily, each at least ``spread`` away from the ones taken, Euclidean in the normalised box), or,
without ``--from``, the best of an initial sample (the box centre plus a seeded Latin hypercube of
``init - 1`` points). Every start runs a compass (generalised pattern) search: each iteration polls
``x +- h e_k`` along every free coordinate and, after a successful move, one pattern point
``x + (x - x_previous)``; the incumbent moves to the best poll point that improves it by more than
``1e-4`` relative, else ``h`` is halved; a start has converged when ``h < min_step``, and the next
start is then taken (budget permitting). With ``model`` (default), a failed poll at a step
``h <= model_step`` is followed, before ``h`` is halved, by the ``d (d - 1) / 2`` cross points
``x + h (e_i + e_j)`` and then by the maximiser, within ``2 h``, of the quadratic that the poll and
cross points determine: it follows ridges oblique to the axes (docs/optimize.md: the jump has one
in (eta_i, mu_ratio)). ``poll: rotating`` polls along a seeded random orthogonal basis instead.
The polls of all running starts form one batch, solved in
parallel by :func:`snapjump_cli.sweep.run.run_sweep`. Infeasible designs (invalid geometry, no snap,
failed, ``mesh_sensitive``, no jump height) are never accepted (extreme barrier). The search is
deterministic: no result depends on the number of jobs or on completion order.

Method ``differential_evolution``: :func:`scipy.optimize.differential_evolution` on the normalised
box (``best1bin``, population ``popsize * d``, Latin-hypercube start, ``rng = seed``, deferred
updating so that a whole generation is one parallel batch, no polish), the best ``--from`` row as
``x0``; infeasible designs score 0.

Evaluations. Every design asked is solved once into a cache sweep file ``<output stem>.evals.parquet``
(the sweep schema; its points are the designs in the order asked), so re-running the same spec and
seed asks the same designs and finds them solved (resumable: an interrupted run loses only unsolved
designs). The budget counts designs meshed and solved (invalid geometries are rejected without a
solve and are not counted; a design asked twice is solved once).

Confirmation. The best feasible designs, best first, are re-solved on a finer mesh (``nt + 1``
elements through the thickness and elements half as long along the arcs:
``aspect * (nt + 1) / (2 nt)``) into ``<output stem>.confirm.parquet``; the first whose objective
holds within ``tolerance`` (relative) and that is still feasible is the answer; at most
``candidates`` designs are tried (``n_jobs`` of them per parallel batch; the answer does not depend
on it).

Output: every evaluation as a row of the sweep schema plus ``iteration`` and ``stage``
(``start``, ``init``, ``poll``, ``pattern``, ``cross``, ``model``, ``de``, ``confirm``) in the order
asked (the row number is the evaluation number; the confirmation rows come last).
"""
from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np
import pandas as pd

from snapjump_cli.optimize.evaluate import Evaluation, Evaluator, confirm
from snapjump_cli.optimize.search import Box, candidates_from, differential_evolution, pattern_search
from snapjump_cli.optimize.spec import (
    PARAMETERS,
    OptimizeInputError,
    OptimizeSpec,
    cache_paths,
    check_cache,
    finer_mesh,
)
from snapjump_cli.settings import MeshSettings

__all__ = ["OptimizeResult", "run_optimize", "write_result", "check_output", "SAME_SEARCH"]

log = logging.getLogger(__name__)


# ---- confirmation and result ---------------------------------------------------------------------
@dataclass
class OptimizeResult:
    """What :func:`run_optimize` found.

    Attributes
    ----------
    table : pandas.DataFrame
        Every evaluation (sweep schema + ``iteration``, ``stage``; confirmation rows last).
    best : dict or None
        The chosen design's five parameters (confirmed if confirmation is on), or ``None``.
    best_row, confirm_row : dict or None
        Its row on the search mesh and on the finer mesh (with ``y_jump_m``).
    objective_value, y_jump_m, y_jump_confirmed_m, dE_J, dy_pole_m, h_imp_m : float
        Of the chosen design (search mesh; ``y_jump_confirmed_m`` on the finer mesh).
    confirmed : bool
    confirm_mesh : MeshSettings or None
    confirm_tried : list
        ``(parameters, objective on the search mesh, on the finer mesh or NaN, held)`` per candidate.
    n_evaluations : int
        Solves of the search (designs meshed and solved; invalid geometries excluded).
    n_invalid : int
        Designs rejected by the geometry check (not solved).
    n_resumed : int
        Solves found already done in the cache.
    baseline_y_jump_m : float
        Best y_jump_m of the ``--from`` rows inside the box, else of the start points.
    baseline_design : tuple or None
    path : list of dict
        The chosen design's path: the incumbents of its local search (pattern), or the running
        best (differential evolution): evaluation number, parameters, objective.
    sensitivity : dict
        The last complete poll around the chosen design (pattern): step ``h`` (normalised),
        ``{param+/-: objective}``.
    converged : bool
        The local search that found the chosen design converged there (its poll step fell below
        ``min_step`` with no better neighbour) before the budget ran out (pattern only).
    iterations : int
    wall_s : float
    """

    table: pd.DataFrame
    spec: OptimizeSpec
    best: dict | None = None
    best_row: dict | None = None
    confirm_row: dict | None = None
    objective_value: float = math.nan
    y_jump_m: float = math.nan
    y_jump_confirmed_m: float = math.nan
    dE_J: float = math.nan
    dy_pole_m: float = math.nan
    h_imp_m: float = math.nan
    confirmed: bool = False
    confirm_mesh: MeshSettings | None = None
    confirm_tried: list = field(default_factory=list)
    n_evaluations: int = 0
    n_invalid: int = 0
    n_resumed: int = 0
    baseline_y_jump_m: float = math.nan
    baseline_design: tuple | None = None
    path: list = field(default_factory=list)
    sensitivity: dict = field(default_factory=dict)
    converged: bool = False
    iterations: int = 0
    wall_s: float = 0.0

    def summary(self) -> dict[str, Any]:
        """The JSON summary (``best``, ``y_jump_m``, ``y_jump_confirmed_m``, ``dE_J``, ``dy_pole_m``,
        ``h_imp_m``, ``n_evaluations``, ``baseline_y_jump_m`` and extras); NaN -> ``None``."""
        def num(x: Any) -> Any:
            return None if x is None or (isinstance(x, float) and not math.isfinite(x)) else x

        base = None if self.baseline_design is None else dict(zip(PARAMETERS, self.baseline_design))
        return {
            "best": self.best,
            "y_jump_m": num(self.y_jump_m),
            "y_jump_confirmed_m": num(self.y_jump_confirmed_m),
            "dE_J": num(self.dE_J),
            "dy_pole_m": num(self.dy_pole_m),
            "h_imp_m": num(self.h_imp_m),
            "n_evaluations": self.n_evaluations,
            "baseline_y_jump_m": num(self.baseline_y_jump_m),
            "baseline_design": base,
            "objective": self.spec.objective,
            "objective_value": num(self.objective_value),
            "confirmed": self.confirmed,
            "confirm_mesh": None if self.confirm_mesh is None else self.confirm_mesh.as_dict(),
            "confirm_tried": [{"design": dict(zip(PARAMETERS, p)), "search": num(a), "finer": num(b), "held": h}
                              for p, a, b, h in self.confirm_tried],
            "method": self.spec.method,
            "seed": self.spec.seed,
            "budget": self.spec.budget,
            "n_invalid_geometry": self.n_invalid,
            "n_resumed": self.n_resumed,
            "iterations": self.iterations,
            "converged": self.converged,
            "sensitivity": {k: num(v) for k, v in self.sensitivity.items()},
            "wall_s": self.wall_s,
        }


def _seed_from(from_df: pd.DataFrame | None, box: Box, spec: OptimizeSpec
               ) -> tuple[list[tuple[float, ...]], float, tuple | None]:
    """Start points and baseline from the ``--from`` rows (none without them); warns when no row
    lies inside the box or the rows were solved on another mesh."""
    cands: list[tuple[float, ...]] = []
    baseline, base_design = math.nan, None
    if from_df is not None:
        cands, baseline, base_design = candidates_from(from_df, box, spec)
        if not cands:
            log.warning("--from: no feasible row lies inside the box; starting from an initial sample")
        if "mesh_nt" in from_df.columns and len(from_df):
            m = spec.sweep.mesh
            same = ((from_df["mesh_order"] == m.order) & (from_df["mesh_nt"] == m.nt)
                    & np.isclose(from_df["mesh_aspect"].astype(float), m.aspect)).fillna(False).all()
            if not same:
                log.warning("--from rows were solved on another mesh than the spec's %s: their values "
                            "(the baseline) are not exactly comparable", m)
    return cands, baseline, base_design


def _baseline_of_starts(ev: Evaluator, baseline: float, base_design: tuple | None
                        ) -> tuple[float, tuple | None]:
    """The best y_jump_m of the start points and its design (``baseline``, ``base_design`` if none)."""
    starts = [e for e in ev.evals if e.stage in ("start", "init") and e.row is not None
              and np.isfinite(float(e.row.get("y_jump_m") or np.nan)) and math.isfinite(e.f)]
    if starts:
        b = max(starts, key=lambda e: (float(e.row["y_jump_m"]), -e.number))
        baseline, base_design = float(b.row["y_jump_m"]), b.params
    return baseline, base_design


def _describe_chosen(result: OptimizeResult, chosen: Evaluation, ev: Evaluator, locals_: list) -> None:
    """Fill ``result`` with the chosen design: its values, its path (the incumbents of the local
    search that found it, else the running best) and the last poll around it."""
    r = chosen.row
    result.best = dict(zip(PARAMETERS, chosen.params))
    result.best_row = r
    result.objective_value = chosen.f
    for k in ("y_jump_m", "dE_J", "dy_pole_m", "h_imp_m"):
        setattr(result, k, float(r[k]))
    # its path and the last poll around it
    owner = None
    for lc in locals_:
        if any(e is chosen for e in lc.path):
            owner = lc
    if owner is not None:
        steps = owner.path[: next(i for i, e in enumerate(owner.path) if e is chosen) + 1]
        result.converged = owner.done and not owner.merged and owner.e is chosen
        if owner.e is chosen and owner.last_poll:
            result.sensitivity = {"h": owner.last_h, "f": chosen.f, **owner.last_poll}
    else:  # running best up to the chosen design
        steps, cur = [], -math.inf
        for e in ev.evals:
            if math.isfinite(e.f) and e.f > cur:
                steps.append(e)
                cur = e.f
            if e is chosen:
                break
        if steps and steps[-1] is not chosen:
            steps.append(chosen)
    result.path = [{"evaluation": e.number, "iteration": e.iteration, **dict(zip(PARAMETERS, e.params)),
                    "objective": e.f} for e in steps]


def run_optimize(
    spec: OptimizeSpec,
    *,
    output: str | Path | None = None,
    n_jobs: int | None = None,
    budget: int | None = None,
    from_df: pd.DataFrame | None = None,
    solve_fn: Callable | None = None,
    warm_up_fn: Callable | None = None,
    on_batch: Callable[[int, int, float], None] | None = None,
) -> OptimizeResult:
    """Search the box of ``spec`` for the design with the highest objective, then confirm it.

    Parameters
    ----------
    spec
        The validated spec (:func:`load_spec`).
    output
        The result file (default ``spec.output``); its caches go next to it (:func:`cache_paths`).
        This function writes only the caches; :func:`write_result` writes ``output``.
    n_jobs
        Parallel workers (default ``spec.sweep.n_jobs``).
    budget
        Overrides ``spec.budget``.
    from_df
        A result table (:func:`read_from`) whose best rows inside the box seed the search.
    solve_fn, warm_up_fn
        Injected solver (see :func:`snapjump_cli.sweep.run.run_sweep`).
    on_batch
        Called after every batch with (solves so far, budget, best objective so far).

    Returns
    -------
    OptimizeResult
    """
    t0 = time.perf_counter()
    output = Path(output if output is not None else spec.output)
    if budget is not None:
        spec = spec.replace(budget=int(budget))
    n_jobs = int(n_jobs if n_jobs is not None else spec.sweep.n_jobs)
    evals_path, confirm_path = cache_paths(output)
    check_cache(evals_path, spec.sweep)
    if spec.confirm.enabled:
        check_cache(confirm_path, spec.sweep.replace(mesh=finer_mesh(spec.sweep.mesh)))
    box = Box(spec.bounds)
    cands, baseline, base_design = _seed_from(from_df, box, spec)
    ev = Evaluator(spec, evals_path, n_jobs, spec.budget, solve_fn, warm_up_fn, on_batch)
    if spec.method == "pattern":
        info = pattern_search(ev, box, spec, cands)
    else:
        info = differential_evolution(ev, box, spec, cands)

    result = OptimizeResult(table=pd.DataFrame(), spec=spec, iterations=info["iterations"])
    result.n_evaluations = ev.n_solves
    result.n_invalid = sum(1 for e in ev.evals if not e.valid)
    result.n_resumed = ev.n_resumed
    if from_df is None or not math.isfinite(baseline):  # the best of the start points
        baseline, base_design = _baseline_of_starts(ev, baseline, base_design)
    result.baseline_y_jump_m, result.baseline_design = baseline, base_design

    chosen: Evaluation | None = None
    confirm_rows: list[dict] = []
    if spec.confirm.enabled and ev.best() is not None:
        chosen, crow, tried, confirm_rows = confirm(ev, spec, confirm_path, n_jobs, solve_fn)
        result.confirm_tried = tried
        result.confirm_mesh = finer_mesh(spec.sweep.mesh)
        if chosen is not None:
            result.confirmed = True
            result.confirm_row = crow
            result.y_jump_confirmed_m = float(crow["y_jump_m"])
    elif not spec.confirm.enabled:
        chosen = ev.best()
    if chosen is not None:
        _describe_chosen(result, chosen, ev, info["locals"])

    rows = []
    for e in ev.evals:
        r = dict(e.row or {})
        r.update(iteration=e.iteration, stage=e.stage)
        rows.append(r)
    result.table = _table(rows + confirm_rows)
    result.wall_s = time.perf_counter() - t0
    return result


def _table(rows: list[dict]) -> pd.DataFrame:
    """Rows in the sweep schema plus ``iteration`` and ``stage``."""
    from snapjump_cli.sweep import results as res

    df = res.rows_to_table(rows).to_pandas(types_mapper=res.pandas_types_mapper(), use_threads=res.ARROW_THREADS)
    df["iteration"] = pd.array([int(r.get("iteration", 0)) for r in rows], dtype="Int64")
    df["stage"] = pd.array([str(r.get("stage", "")) for r in rows], dtype="string")
    return df


def write_result(result: OptimizeResult, output: str | Path, extra_meta: Mapping[str, Any] | None = None) -> Path:
    """Write the evaluation table atomically, with provenance and the summary in its metadata."""
    from snapjump_cli.sweep import results as res

    meta = res.provenance(result.spec.to_dict(), command="optimize", summary=result.summary(), **dict(extra_meta or {}))
    return res.write_frame_atomic(result.table, output, meta)


#: The parts of a spec that make two runs the same search (its budget, jobs, chunk size, resource
#: limits and file name may differ: a run with a larger budget continues the search).
SAME_SEARCH = ("bounds", "objective", "seed", "method", "search", "confirm", "jump", "R_i", "materials", "ring",
               "mesh", "solver")


def _same_search(old: Mapping[str, Any], spec: OptimizeSpec) -> list[str]:
    """The parts of :data:`SAME_SEARCH` in which the recorded spec ``old`` differs from ``spec``."""
    import json

    from snapjump_cli.settings import without_limits

    new = json.loads(json.dumps(spec.to_dict(), default=str))
    norm = {"solver": without_limits}
    return [k for k in SAME_SEARCH if norm.get(k, lambda v: v)(old.get(k)) != norm.get(k, lambda v: v)(new.get(k))]


def check_output(output: str | Path, spec: OptimizeSpec, overwrite: bool = False) -> None:
    """Refuse to replace what is not a run of this search: an existing ``output`` must be the result
    of ``snapjump optimize`` with the same spec (:data:`SAME_SEARCH`), and its plots
    (:func:`plot_files`) may be replaced only then; ``overwrite`` allows both.

    Raises
    ------
    OptimizeInputError
        Naming the file and why it is not this run's (a sweep's results, another spec, ...).
    """
    from snapjump_cli.optimize.plots import plot_files
    from snapjump_cli.sweep import results as res

    output = Path(output)
    own = False
    if output.exists():
        try:
            meta = res.read_metadata(output)
        except Exception:  # noqa: BLE001 - any unreadable file is simply not ours
            meta = None
        if meta is None:
            why = "is not a result file"
        elif meta.get("command") != "optimize":
            what = f"snapjump {meta['command']}" if meta.get("command") else "another program"
            why = f"holds the results of {what}, not of this optimize run"
        elif diffs := _same_search(meta.get("config") or {}, spec):
            why = f"holds an optimize run of another spec ({', '.join(diffs)} differ)"
        else:
            own = True
        if not own and not overwrite:
            raise OptimizeInputError(f"{output}: exists and {why}; choose another -o/--output, or pass --overwrite "
                                     f"to replace it")
    if not own and not overwrite:
        for p in plot_files(output):
            if p.exists():
                raise OptimizeInputError(f"{p}: exists and {output} is not a run of this spec; choose another "
                                         f"-o/--output, or pass --overwrite to replace it")

