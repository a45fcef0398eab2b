"""Search the continuous design space for the highest jump (``snapjump optimize``).

Spec (YAML, validated like a sweep config: every error is a :class:`~snapjump_cli.config.ConfigError`
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
parallel by :func:`snapjump_cli.sweep.run_sweep`. Infeasible designs (invalid geometry, no snap,
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

import dataclasses
import logging
import math
import os
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np
import pandas as pd
import yaml

from snapjump_cli.config import (
    GRID_AXES,
    ConfigError,
    DesignPoint,
    SweepConfig,
    _axis_check,
    _Ctx,
    parse_config,
)
from snapjump_cli.jump import JumpParams
from snapjump_cli.settings import MeshSettings

__all__ = [
    "PARAMETERS",
    "OBJECTIVES",
    "METHODS",
    "STAGES",
    "OptimizeSpec",
    "SearchSettings",
    "ConfirmSettings",
    "OptimizeResult",
    "OptimizeInputError",
    "load_spec",
    "parse_spec",
    "finer_mesh",
    "read_from",
    "run_optimize",
    "cache_paths",
    "check_cache",
    "write_result",
    "plot_progress",
    "plot_path",
    "make_plots",
]

log = logging.getLogger(__name__)

#: The five design parameters, in the order of :data:`snapjump_cli.config.GRID_AXES`, and their
#: result-table columns.
PARAMETERS: tuple[str, ...] = GRID_AXES
COLUMNS: dict[str, str] = {"eta_i": "eta_i", "theta_i": "theta_i_deg", "eta_o": "eta_o",
                           "theta_o": "theta_o_deg", "mu_ratio": "mu_ratio"}
OBJECTIVES: tuple[str, ...] = ("y_jump_m", "dE_J")
METHODS: tuple[str, ...] = ("pattern", "differential_evolution")
STAGES: tuple[str, ...] = ("start", "init", "poll", "pattern", "cross", "model", "de", "confirm")
#: A poll point must beat the incumbent by this fraction to be accepted (the objective is only
#: piecewise smooth: continuation paths and lower states switch between neighbouring designs).
IMPROVE_REL = 1e-4
_SIG_DIGITS = 10  # design parameters are rounded to this many significant digits (stable keys)

_TOP_KEYS: dict[str, str] = {
    "bounds": "a mapping with keys " + ", ".join(PARAMETERS),
    "objective": "one of " + ", ".join(OBJECTIVES),
    "budget": "the number of solves (an integer >= 1)",
    "seed": "an integer >= 0",
    "method": "one of " + ", ".join(METHODS),
    "search": "a mapping {starts, init, step, min_step, spread, popsize, poll, model, model_step}",
    "confirm": "a mapping {tolerance, candidates} or false",
    "jump": "a mapping {rho, c_d, alpha}",
    "R_i": "the inner-cap radius in metres (> 0)",
    "materials": "a mapping {mu_i, J_m}",
    "ring": "a mapping {t_ring_frac, w_ring_frac}",
    "mesh": "a mapping of mesh settings",
    "solver": "a mapping of solver settings",
    "output": "the result file path",
    "n_jobs": "the number of parallel jobs",
    "chunk_size": "the number of results per part file",
}
#: Keys handed to :func:`snapjump_cli.config.parse_config` (validated exactly as in a sweep).
_SWEEP_KEYS = ("R_i", "materials", "ring", "mesh", "solver", "output", "n_jobs", "chunk_size")
_BOUND_EXPECTED = "[lo, hi] (two numbers, lo <= hi) or a single number (a fixed value)"
_SEARCH_KEYS = {"starts": "an integer >= 1", "init": "an integer >= 1", "step": "a number in (0, 0.5]",
                "min_step": "a number in (0, step]", "spread": "a number >= 0", "popsize": "an integer >= 2",
                "poll": "coordinate or rotating", "model": "true or false", "model_step": "a number in (0, 0.5]"}
POLLS: tuple[str, ...] = ("coordinate", "rotating")
_CONFIRM_KEYS = {"tolerance": "a number > 0", "candidates": "an integer >= 1"}
_JUMP_KEYS = {"rho": "the rubber density [kg/m^3] (> 0)", "c_d": "the dashpot coefficient [kg/s] (>= 0)",
              "alpha": "the restitution coefficient in [0, 1]"}


class OptimizeInputError(ValueError):
    """Bad input found at run time (e.g. an unreadable ``--from`` file); the CLI exits 2."""


# ---- spec --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SearchSettings:
    """Settings of the search methods.

    Attributes
    ----------
    starts : int
        Local searches running at once (method ``pattern``).
    init : int or None
        Size of the initial sample without ``--from`` (box centre + Latin hypercube); default
        ``2 d + 1``.
    step, min_step : float
        Initial and final poll step in the normalised box (``pattern``).
    spread : float
        Minimum normalised (Euclidean) distance between start points.
    popsize : int
        Population per free parameter (``differential_evolution``).
    poll : str
        Poll directions (``pattern``): ``coordinate`` (``+-`` each free parameter) or ``rotating``
        (``+-`` the columns of a seeded random orthogonal matrix, new at every iteration).
    model : bool
        When a poll at a step ``h <= model_step`` fails, before halving ``h``: evaluate the
        ``d (d - 1) / 2`` cross points ``x + h (e_i + e_j)`` (with the poll they determine a full
        quadratic model), then the model's maximiser within ``2 h`` of ``x`` (``pattern``). It
        follows ridges that are oblique to the poll directions, which a compass search cannot.
    model_step : float
        Largest poll step at which the model is built.
    """

    starts: int = 3
    init: int | None = None
    step: float = 0.125
    min_step: float = 1.0 / 128.0
    spread: float = 0.2
    popsize: int = 8
    poll: str = "coordinate"
    model: bool = True
    model_step: float = 1.0 / 16.0


@dataclass(frozen=True)
class ConfirmSettings:
    """Confirmation on the finer mesh: relative ``tolerance`` on the objective, at most
    ``candidates`` designs tried; ``enabled = False`` skips it."""

    enabled: bool = True
    tolerance: float = 0.02
    candidates: int = 5


@dataclass(frozen=True)
class OptimizeSpec:
    """A validated optimisation spec (defaults applied).

    Attributes
    ----------
    bounds : dict
        Parameter (:data:`PARAMETERS`) -> ``(lo, hi)``; ``lo == hi`` is a fixed value.
    objective : str
        ``y_jump_m`` or ``dE_J`` (maximised).
    budget : int
        Number of solves.
    seed : int
    method : str
        One of :data:`METHODS`.
    search : SearchSettings
    confirm : ConfirmSettings
    jump : JumpParams
    sweep : SweepConfig
        Shared design constants, mesh, solver, ``n_jobs``, ``chunk_size`` and the default output.
    source : str
    raw : dict
    """

    bounds: dict[str, tuple[float, float]]
    sweep: SweepConfig
    objective: str = "y_jump_m"
    budget: int = 300
    seed: int = 0
    method: str = "pattern"
    search: SearchSettings = field(default_factory=SearchSettings)
    confirm: ConfirmSettings = field(default_factory=ConfirmSettings)
    jump: JumpParams = field(default_factory=JumpParams)
    source: str = "<dict>"
    raw: dict = field(default_factory=dict, compare=False)

    @property
    def free(self) -> tuple[str, ...]:
        """The free parameters (``lo < hi``), in the order of :data:`PARAMETERS`."""
        return tuple(p for p in PARAMETERS if self.bounds[p][0] < self.bounds[p][1])

    @property
    def output(self) -> Path:
        """Default output file (``output:`` of the spec, else ``results/<spec stem>.parquet``)."""
        return self.sweep.output

    def replace(self, **changes: Any) -> "OptimizeSpec":
        """A copy with some fields replaced."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """The resolved spec as plain JSON-able data."""
        sw = self.sweep.to_dict()
        for k in ("points", "grid", "n_designs", "output"):
            sw.pop(k, None)
        return {
            "bounds": {p: list(self.bounds[p]) for p in PARAMETERS},
            "objective": self.objective, "budget": self.budget, "seed": self.seed, "method": self.method,
            "search": dataclasses.asdict(self.search), "confirm": dataclasses.asdict(self.confirm),
            "jump": {k: getattr(self.jump, k) for k in ("rho", "c_d", "alpha", "g")},
            **sw,
        }


def _parse_bound(ctx: _Ctx, name: str, value: Any) -> tuple[float, float]:
    path = f"bounds.{name}"
    ok, expected = _axis_check(name)
    if isinstance(value, (list, tuple)):
        if len(value) != 2:
            raise ConfigError(ctx.source, path, f"expected {_BOUND_EXPECTED}, got a list of {len(value)}")
        lo = ctx.number(f"{path}[0]", value[0], expected)
        hi = ctx.number(f"{path}[1]", value[1], expected)
        for j, x in enumerate((lo, hi)):
            if not ok(x):
                raise ctx.fail(f"{path}[{j}]", expected, value[j])
        if lo > hi:
            raise ConfigError(ctx.source, f"{path}[1]", f"expected hi >= lo = {lo:g}, got {hi:g}")
        return lo, hi
    if isinstance(value, Mapping) or value is None or isinstance(value, bool):
        raise ctx.fail(path, _BOUND_EXPECTED, value)
    x = ctx.number(path, value, _BOUND_EXPECTED)
    if not ok(x):
        raise ctx.fail(path, expected, value)
    return x, x


def _choice(ctx: _Ctx, path: str, value: Any, options: Sequence[str]) -> str:
    if not isinstance(value, str) or value not in options:
        raise ctx.fail(path, "one of " + ", ".join(options), value)
    return value


def parse_spec(doc: Any, source: str = "<dict>") -> OptimizeSpec:
    """Validate a loaded optimisation spec and apply the defaults.

    Parameters
    ----------
    doc
        The object returned by :func:`yaml.safe_load`.
    source
        Name used in error messages (usually the file path).

    Returns
    -------
    OptimizeSpec

    Raises
    ------
    ConfigError
        On the first violation, naming ``source``, the key path and what was expected.
    """
    ctx = _Ctx(source)
    if doc is None:
        raise ConfigError(source, "bounds", "missing required key (the file is empty); expected " + _TOP_KEYS["bounds"])
    top = ctx.mapping("", doc, _TOP_KEYS, required=("bounds",))
    b = ctx.mapping("bounds", top["bounds"], {p: _BOUND_EXPECTED for p in PARAMETERS}, required=PARAMETERS)
    bounds = {p: _parse_bound(ctx, p, b[p]) for p in PARAMETERS}
    if all(lo == hi for lo, hi in bounds.values()):
        raise ConfigError(source, "bounds", "expected at least one free parameter ([lo, hi] with lo < hi), got all fixed")
    kw: dict[str, Any] = {"bounds": bounds, "source": source, "raw": dict(top)}
    if top.get("objective") is not None:
        kw["objective"] = _choice(ctx, "objective", top["objective"], OBJECTIVES)
    if top.get("method") is not None:
        kw["method"] = _choice(ctx, "method", top["method"], METHODS)
    if top.get("budget") is not None:
        kw["budget"] = ctx.integer("budget", top["budget"], minimum=1)
    if top.get("seed") is not None:
        kw["seed"] = ctx.integer("seed", top["seed"], minimum=0)

    if top.get("search") is not None:
        s = ctx.mapping("search", top["search"], _SEARCH_KEYS)
        skw: dict[str, Any] = {}
        for k in ("starts", "init"):
            if k in s:
                skw[k] = ctx.integer(f"search.{k}", s[k], minimum=1)
        if "popsize" in s:
            skw["popsize"] = ctx.integer("search.popsize", s["popsize"], minimum=2)
        if "poll" in s:
            skw["poll"] = _choice(ctx, "search.poll", s["poll"], POLLS)
        if "model" in s:
            skw["model"] = ctx.boolean("search.model", s["model"])
        for k, good in (("step", lambda x: 0 < x <= 0.5), ("min_step", lambda x: x > 0), ("spread", lambda x: x >= 0),
                        ("model_step", lambda x: 0 < x <= 0.5)):
            if k in s:
                x = ctx.number(f"search.{k}", s[k], _SEARCH_KEYS[k])
                if not good(x):
                    raise ctx.fail(f"search.{k}", _SEARCH_KEYS[k], s[k])
                skw[k] = x
        search = SearchSettings(**skw)
        if search.min_step > search.step:
            raise ConfigError(source, "search.min_step", f"expected min_step <= step = {search.step:g}, got {search.min_step:g}")
        kw["search"] = search

    if "confirm" in top and top["confirm"] is not None:
        c = top["confirm"]
        if isinstance(c, bool):
            kw["confirm"] = ConfirmSettings(enabled=c)
        else:
            c = ctx.mapping("confirm", c, _CONFIRM_KEYS)
            ckw: dict[str, Any] = {}
            if "tolerance" in c:
                ckw["tolerance"] = ctx.positive("confirm.tolerance", c["tolerance"])
            if "candidates" in c:
                ckw["candidates"] = ctx.integer("confirm.candidates", c["candidates"], minimum=1)
            kw["confirm"] = ConfirmSettings(**ckw)

    if top.get("jump") is not None:
        j = ctx.mapping("jump", top["jump"], _JUMP_KEYS)
        jkw = {}
        for k in j:
            x = ctx.number(f"jump.{k}", j[k], _JUMP_KEYS[k])
            good = {"rho": x > 0, "c_d": x >= 0, "alpha": 0 <= x <= 1}[k]
            if not good:
                raise ctx.fail(f"jump.{k}", _JUMP_KEYS[k], j[k])
            jkw[k] = x
        kw["jump"] = JumpParams(**jkw)

    # the sweep blocks: validated by the sweep's own parser (same key paths and messages)
    sub = {k: top[k] for k in _SWEEP_KEYS if k in top}
    sub["points"] = [{p: bounds[p][0] for p in PARAMETERS}]
    kw["sweep"] = parse_config(sub, source)
    return OptimizeSpec(**kw)


def load_spec(path: str | Path) -> OptimizeSpec:
    """Read and validate an optimisation spec file (see the module docstring).

    Raises
    ------
    ConfigError
        The file is missing or unreadable, not valid YAML, or does not match the schema.
    """
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(source, "", "file not found") from None
    except IsADirectoryError:
        raise ConfigError(source, "", "expected a YAML file, got a directory") from None
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError(source, "", f"cannot read the file ({e})") from None
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(e, "problem", None) or str(e).splitlines()[0]
        raise ConfigError(source, "", f"YAML syntax error{where}: {problem}") from None
    return parse_spec(doc, source)


def finer_mesh(mesh: MeshSettings) -> MeshSettings:
    """The confirmation mesh: one more element through the thickness and elements half as long
    along the arcs (``aspect * (nt + 1) / (2 nt)``)."""
    nt = mesh.nt + 1
    return MeshSettings(order=mesh.order, nt=nt, aspect=mesh.aspect * nt / (2 * mesh.nt))


def cache_paths(output: str | Path) -> tuple[Path, Path]:
    """The evaluation and confirmation cache files next to ``output``:
    ``<stem>.evals.parquet`` and ``<stem>.confirm.parquet``."""
    output = Path(output)
    stem = output.name.removesuffix(".parquet")
    return output.with_name(stem + ".evals.parquet"), output.with_name(stem + ".confirm.parquet")


# ---- --from --------------------------------------------------------------------------------------
def read_from(path: str | Path) -> pd.DataFrame:
    """Rows of a sweep (or ranked, or optimize) result: a parquet file, its ``.parts`` folder, or a
    file path whose ``.parts`` folder holds the rows of an unfinished sweep.

    Raises
    ------
    OptimizeInputError
        Nothing readable there, or the columns of a result table are missing.
    """
    from snapjump_cli import results as res
    from snapjump_cli.sweep import parts_dir

    path = Path(path)
    if path.is_dir():
        files = sorted(path.glob("part-*.parquet"))
    elif path.exists():
        files = [path]
    else:
        files = sorted(parts_dir(path).glob("part-*.parquet"))
        if files:
            log.warning("%s does not exist: using the %d part files of the unfinished sweep in %s",
                        path, len(files), parts_dir(path))
    if not files:
        raise OptimizeInputError(f"--from: {path}: file not found (no result file or part files)")
    try:
        df = pd.concat([res.read_results(f) for f in files], ignore_index=True)
    except Exception as e:  # noqa: BLE001 - any unreadable file is bad input
        raise OptimizeInputError(f"--from: {path}: not a readable parquet result file ({str(e).splitlines()[0]})") from None
    need = ["status", *COLUMNS.values(), "dE_J", "dy_pole_m", "h_imp_m", "V_inner_solid_m3", "V_outer_solid_m3", "R_i"]
    missing = [c for c in need if c not in df.columns]
    if missing:
        raise OptimizeInputError(f"--from: {path}: not a sweep result table (missing column(s) {', '.join(missing)})")
    if "key" in df.columns:
        df = df.drop_duplicates(subset="key", keep="last")
    return df.reset_index(drop=True)


# ---- evaluation ----------------------------------------------------------------------------------
def _round(x: float) -> float:
    return float(f"{float(x):.{_SIG_DIGITS}g}")


def _objective_values(df: pd.DataFrame, objective: str, params: JumpParams) -> pd.DataFrame:
    """``df`` with ``y_jump_m`` and ``_f`` (the objective, NaN where infeasible), in its order."""
    from snapjump_cli.rank import rank_results

    from snapjump_cli.rank import RANK_COLUMNS

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
class _Eval:
    key: str
    params: tuple[float, ...]   # the five parameters (physical, rounded)
    iteration: int
    stage: str
    number: int                 # evaluation number (order asked)
    valid: bool                 # geometry valid (a solve was needed)
    f: float = math.nan         # objective (NaN: infeasible)
    row: dict | None = None


class _Evaluator:
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
        self.evals: list[_Eval] = []
        self.by_key: dict[str, _Eval] = {}
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
        from snapjump_cli.sweep import design_key

        return design_key(self.point(params), mesh or self.spec.sweep.mesh, self.spec.sweep.solver)

    def valid(self, params: Sequence[float]) -> bool:
        from snapjump_cli.geometry import Design, InvalidDesign

        try:
            Design(**self.point(params).design_kwargs())
        except InvalidDesign:
            return False
        return True

    @property
    def remaining(self) -> int:
        return self.budget - self.n_solves

    def best(self) -> _Eval | None:
        feas = [e for e in self.evals if math.isfinite(e.f)]
        return max(feas, key=lambda e: (e.f, -e.number)) if feas else None

    def ask(self, requests: Sequence[tuple[Sequence[float], str]], iteration: int) -> list[_Eval | None]:
        """Evaluate designs (in priority order); returns one record per request, ``None`` where the
        budget ran out before it. Designs asked before are not solved again."""
        out: list[_Eval | None] = []
        new: list[_Eval] = []
        for params, stage in requests:
            params = tuple(_round(x) for x in params)
            k = self.key(params)
            e = self.by_key.get(k)
            if e is None:
                valid = self.valid(params)
                if valid and self.remaining <= 0:
                    out.append(None)
                    continue
                e = _Eval(key=k, params=params, iteration=iteration, stage=stage, number=len(self.evals), valid=valid)
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

    def _solve(self, new: list[_Eval]) -> None:
        from snapjump_cli.sweep import run_sweep

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
        scored = _objective_values(df, self.spec.objective, self.spec.jump)
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
    from snapjump_cli import results as res
    from snapjump_cli.sweep import parts_dir

    files = ([cache] if cache.is_file() else []) + sorted(parts_dir(cache).glob("part-*.parquet"))
    frames = [df[df["key"].isin(keys)] for df in (res.read_results(f) for f in files)]
    return pd.concat(frames, ignore_index=True).drop_duplicates(subset="key", keep="last")


def _cached_designs(cache: Path, ev: "_Evaluator", mesh: MeshSettings | None = None) -> dict[str, tuple[float, ...]]:
    """key (on ``mesh``, default the spec's) -> the five parameters of every design recorded in
    ``cache`` (file and part files)."""
    from snapjump_cli import results as res
    from snapjump_cli.sweep import parts_dir

    files = ([cache] if cache.is_file() else []) + sorted(parts_dir(cache).glob("part-*.parquet"))
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

    from snapjump_cli.sweep import run_sweep

    return {"append": True} if "append" in inspect.signature(run_sweep).parameters else {}


_CACHE_SETTINGS = ("mesh", "solver", "materials", "ring", "R_i")


def check_cache(path: str | Path, config: SweepConfig) -> None:
    """Refuse a cache file (or its part files) written with other mesh, solver, material or ring
    settings than ``config``'s (one cache holds one setting).

    Raises
    ------
    OptimizeInputError
        Naming the file and what differs.
    """
    from snapjump_cli import results as res
    from snapjump_cli.sweep import parts_dir

    path = Path(path)
    files = ([path] if path.is_file() else []) + sorted(parts_dir(path).glob("part-*.parquet"))
    if not files:
        return
    want = config.to_dict()
    for f in files:
        try:
            old = res.read_metadata(f).get("config") or {}
        except Exception as e:  # noqa: BLE001 - not a parquet file
            raise OptimizeInputError(f"{f}: not a readable snapjump result file ({str(e).splitlines()[0]}); "
                                     f"remove it or choose another -o/--output") from None
        diffs = [f"{k} {old.get(k)} -> {want.get(k)}" for k in _CACHE_SETTINGS if k in old and old.get(k) != want.get(k)]
        if diffs:
            raise OptimizeInputError(f"{f}: holds evaluations computed with other settings ({'; '.join(diffs)}); "
                                     f"choose another -o/--output, or remove it to start afresh")


def _no_warm_up() -> None:
    """The kernels are compiled by the first batch; later batches skip the warm-up."""


# ---- the search ----------------------------------------------------------------------------------
class _Box:
    """The map between the normalised box of the free parameters and the five parameters."""

    def __init__(self, bounds: Mapping[str, tuple[float, float]]) -> None:
        self.bounds = dict(bounds)
        self.free = [p for p in PARAMETERS if bounds[p][0] < bounds[p][1]]
        self.d = len(self.free)

    def to_params(self, u: Sequence[float]) -> tuple[float, ...]:
        vals = {p: self.bounds[p][0] for p in PARAMETERS}
        for p, x in zip(self.free, u):
            lo, hi = self.bounds[p]
            vals[p] = lo + float(np.clip(x, 0.0, 1.0)) * (hi - lo)
        return tuple(vals[p] for p in PARAMETERS)

    def to_unit(self, params: Sequence[float]) -> np.ndarray:
        vals = dict(zip(PARAMETERS, params))
        return np.array([(vals[p] - self.bounds[p][0]) / (self.bounds[p][1] - self.bounds[p][0]) for p in self.free])

    def contains(self, params: Sequence[float], rtol: float = 1e-9) -> bool:
        for p, x in zip(PARAMETERS, params):
            lo, hi = self.bounds[p]
            tol = rtol * max(1.0, abs(lo), abs(hi))
            if not (lo - tol <= x <= hi + tol):
                return False
        return True


@dataclass
class _Local:
    """One running compass search."""

    ident: int
    x: np.ndarray
    f: float
    h: float
    e: _Eval
    prev: np.ndarray | None = None
    path: list[_Eval] = field(default_factory=list)
    done: bool = False
    merged: bool = False
    phase: str = "poll"         # poll -> (failed, h <= model_step) cross -> model -> poll
    last_poll: dict[str, tuple[float, float]] = field(default_factory=dict)
    last_h: float = math.nan


def _candidates_from(df: pd.DataFrame, box: _Box, spec: OptimizeSpec) -> tuple[list[tuple[float, ...]], float, tuple | None]:
    """Start points from a result table: its feasible rows inside the box, best first; and the
    best y_jump_m of those rows (the baseline) with its design."""
    scored = _objective_values(df, spec.objective, spec.jump)
    params = scored[list(COLUMNS.values())].to_numpy(dtype=float)
    inside = np.array([box.contains(p) for p in params], dtype=bool) if len(params) else np.zeros(0, bool)
    feas = inside & np.isfinite(scored["_f"].to_numpy(dtype=float))
    sc = scored[feas].assign(_p=list(map(tuple, params[feas])))
    sc = sc.sort_values("_f", ascending=False, kind="stable")
    baseline, base_design = math.nan, None
    if len(sc):
        yj = sc["y_jump_m"].to_numpy(dtype=float)
        j = int(np.nanargmax(yj))
        baseline, base_design = float(yj[j]), tuple(float(x) for x in sc["_p"].iloc[j])
    return [tuple(float(x) for x in p) for p in sc["_p"]], baseline, base_design


def _spread_ok(u: np.ndarray, taken: Sequence[np.ndarray], spread: float) -> bool:
    return all(float(np.linalg.norm(u - v)) >= spread for v in taken)


def _initial_sample(box: _Box, n: int, seed: int) -> list[tuple[float, ...]]:
    """The box centre and a seeded Latin hypercube of ``n - 1`` points (one point per stratum
    ``[k/m, (k+1)/m)`` of every free parameter, strata paired at random)."""
    pts = [box.to_params([0.5] * box.d)]
    m = n - 1
    if m > 0:
        rng = np.random.default_rng(seed)
        u = np.empty((m, box.d))
        for j in range(box.d):
            u[:, j] = (rng.permutation(m) + rng.random(m)) / m
        pts += [box.to_params(row) for row in u]
    return pts


def _poll_directions(box: _Box, poll: str, rng: np.random.Generator) -> list[tuple[str, np.ndarray]]:
    """The 2 d poll directions: ``+-`` the unit vectors, or ``+-`` the columns of the Householder
    matrix ``I - 2 v v^T`` of a random unit vector ``v`` (an orthonormal basis; OrthoMADS-style)."""
    d = box.d
    basis = np.eye(d)
    names = list(box.free)
    if poll == "rotating":
        v = rng.standard_normal(d)
        v /= np.linalg.norm(v)
        basis = np.eye(d) - 2.0 * np.outer(v, v)
        names = [f"dir{k}" for k in range(d)]
    out = []
    for k in range(d):
        for sgn, tag in ((-1.0, "-"), (1.0, "+")):
            out.append((names[k] + tag, sgn * basis[:, k]))
    return out


def _quadratic_terms(S: np.ndarray) -> np.ndarray:
    n, d = S.shape
    cols = [np.ones(n)] + [S[:, i] for i in range(d)]
    cols += [S[:, i] * S[:, j] for i in range(d) for j in range(i, d)]
    return np.column_stack(cols)


def _cross_points(box: _Box, lc: _Local) -> list[tuple[str, np.ndarray]]:
    """``x + h (e_i + e_j)``, ``i < j`` (inside the box: a coordinate that would leave it steps back)."""
    out = []
    for i in range(box.d):
        for j in range(i + 1, box.d):
            v = np.zeros(box.d)
            for k in (i, j):
                v[k] = 1.0 if lc.x[k] + lc.h <= 1.0 + 1e-12 else -1.0
            out.append((f"{box.free[i]}+{box.free[j]}", np.clip(lc.x + lc.h * v, 0.0, 1.0)))
    return out


def _model_point(ev: _Evaluator, box: _Box, lc: _Local, rng: np.random.Generator, trust: float = 2.0
                 ) -> np.ndarray | None:
    """The maximiser, within ``trust`` poll steps of the incumbent and inside the box, of the
    quadratic fitted (least squares) to the feasible evaluations within one poll step of it (the
    poll and cross points: the full quadratic is determined); ``None`` when fewer points than
    terms are feasible or the model promises no improvement."""
    d = box.d
    n_terms = 1 + d + d * (d + 1) // 2
    feas = [e for e in ev.evals if math.isfinite(e.f)]
    if len(feas) < n_terms:
        return None
    S = (np.array([box.to_unit(e.params) for e in feas]) - lc.x) / lc.h
    near = np.max(np.abs(S), axis=1) <= 1.0 + 1e-6
    if int(near.sum()) < n_terms:
        return None
    scale = abs(lc.f) if lc.f != 0 else 1.0
    A = _quadratic_terms(S[near])
    b = (np.array([e.f for e in feas])[near] - lc.f) / scale
    coef, *_ = np.linalg.lstsq(A, b, rcond=None)
    g = coef[1:1 + d]
    H = np.zeros((d, d))
    k = 1 + d
    for i in range(d):
        for j in range(i, d):
            H[i, j] += coef[k] if i != j else 2.0 * coef[k]
            if i != j:
                H[j, i] += coef[k]
            k += 1
    lo = np.maximum((0.0 - lc.x) / lc.h, -trust)
    hi = np.minimum((1.0 - lc.x) / lc.h, trust)
    # the best of a seeded sample of the trust box, polished by projected gradient ascent
    cand = lo + (hi - lo) * rng.random((4096, d))
    pred = _quadratic_terms(cand) @ coef
    z = cand[int(np.argmax(pred))]
    step = 1.0 / max(float(np.max(np.abs(np.linalg.eigvalsh(H)))), 1e-12)
    for _ in range(200):
        z = np.clip(z + step * (g + H @ z), lo, hi)
    m = float((_quadratic_terms(z[None, :]) @ coef)[0])
    if not m > 2 * IMPROVE_REL:
        return None
    y = np.clip(lc.x + lc.h * z, 0.0, 1.0)
    return None if np.max(np.abs(y - lc.x)) < 1e-9 else y


def _pattern_search(ev: _Evaluator, box: _Box, spec: OptimizeSpec, cands: list[tuple[float, ...]]) -> dict[str, Any]:
    s = spec.search
    iteration = 0
    queue = list(cands)
    if not queue:  # no usable --from rows: an initial sample
        n_init = s.init or 2 * box.d + 1
        init = ev.ask([(p, "init") for p in _initial_sample(box, n_init, spec.seed)], iteration)
        feas = [e for e in init if e is not None and math.isfinite(e.f)]
        queue = [e.params for e in sorted(feas, key=lambda e: (-e.f, e.number))]
    locals_: list[_Local] = []
    finished: list[_Local] = []
    n_ident = 0

    def take_starts() -> None:
        nonlocal n_ident, queue
        while len(locals_) < s.starts and queue and ev.remaining > 0:
            want = s.starts - len(locals_)
            taken = [lc.x for lc in locals_ + finished]
            picked, rest = [], []
            for p in queue:
                u = box.to_unit(p)
                if len(picked) < want and _spread_ok(u, taken + [box.to_unit(q) for q in picked], s.spread):
                    picked.append(p)
                else:
                    rest.append(p)
            if not picked:
                return
            queue = rest
            got = ev.ask([(p, "start") for p in picked], iteration)
            for p, e in zip(picked, got):
                if e is None or not math.isfinite(e.f):
                    continue
                lc = _Local(ident=n_ident, x=box.to_unit(e.params), f=e.f, h=s.step, e=e, path=[e])
                n_ident += 1
                locals_.append(lc)

    take_starts()
    while locals_ and ev.remaining > 0:
        iteration += 1
        requests: list[tuple[tuple[float, ...], str]] = []
        owners: list[tuple[_Local, str, np.ndarray]] = []
        for lc in sorted(locals_, key=lambda lc: (-lc.f, lc.ident)):
            if lc.phase == "cross":
                for name, y in _cross_points(box, lc):
                    requests.append((box.to_params(y), "cross"))
                    owners.append((lc, name, y))
                continue
            if lc.phase == "model":
                y = _model_point(ev, box, lc, np.random.default_rng([spec.seed, iteration, lc.ident]))
                if y is not None:
                    requests.append((box.to_params(y), "model"))
                    owners.append((lc, "model", y))
                continue
            if lc.prev is not None:  # pattern point after a successful move
                y = np.clip(lc.x + (lc.x - lc.prev), 0.0, 1.0)
                if not np.allclose(y, lc.x):
                    requests.append((box.to_params(y), "pattern"))
                    owners.append((lc, "pattern", y))
            dirs = _poll_directions(box, s.poll, np.random.default_rng([spec.seed, iteration, lc.ident]))
            for name, v in dirs:
                y = np.clip(lc.x + lc.h * v, 0.0, 1.0)
                if np.allclose(y, lc.x):
                    continue
                requests.append((box.to_params(y), "poll"))
                owners.append((lc, name, y))
        got = ev.ask(requests, iteration)
        truncated = any(e is None for e in got)
        for lc in list(locals_):
            mine = [(tag, y, e) for (o, tag, y), e in zip(owners, got) if o is lc]
            best = None
            for tag, y, e in mine:
                if e is not None and math.isfinite(e.f) and e.f > lc.f + IMPROVE_REL * abs(lc.f) \
                        and (best is None or e.f > best[2].f):
                    best = (tag, y, e)
            if best is not None:
                lc.prev, lc.x, lc.f, lc.e = lc.x, best[1], best[2].f, best[2]
                lc.path.append(best[2])
                lc.last_poll, lc.last_h = {}, math.nan
                lc.phase = "poll"
            elif not any(e is None for _, _, e in mine):
                if lc.phase == "poll":
                    # a complete poll around the incumbent, none better: the local sensitivities
                    lc.last_poll = {tag: e.f for tag, y, e in mine if tag != "pattern"}
                    lc.last_h = lc.h
                    lc.prev = None
                if lc.phase == "poll" and s.model and lc.h <= s.model_step * (1 + 1e-9) and box.d > 1:
                    lc.phase = "cross"
                elif lc.phase == "cross":
                    lc.phase = "model"
                else:
                    lc.phase = "poll"
                    lc.h /= 2.0
                    if lc.h < s.min_step:
                        lc.done = True
        # merge starts that met: the worse one stops
        for lc in sorted(locals_, key=lambda lc: (-lc.f, lc.ident)):
            if lc.done:
                continue
            for other in locals_:
                if other is lc or other.done or (other.f, -other.ident) < (lc.f, -lc.ident):
                    continue
                if float(np.max(np.abs(other.x - lc.x))) < 0.5 * lc.h:
                    lc.done = lc.merged = True
                    log.info("start %d met start %d; it stops", lc.ident, other.ident)
                    break
        for lc in [lc for lc in locals_ if lc.done]:
            locals_.remove(lc)
            finished.append(lc)
            if not lc.merged:
                log.info("start %d converged at f = %.6g (h = %.3g)", lc.ident, lc.f, lc.h)
        b = ev.best()
        log.info("iteration %d: %d solves of %d, %d starts running, best %.6g", iteration, ev.n_solves,
                 ev.budget, len(locals_), b.f if b is not None else math.nan)
        if truncated:
            break
        take_starts()
    return {"locals": finished + locals_, "iterations": iteration}


def _differential_evolution(ev: _Evaluator, box: _Box, spec: OptimizeSpec, cands: list[tuple[float, ...]]) -> dict[str, Any]:
    from scipy.optimize import differential_evolution

    pop = spec.search.popsize * box.d
    maxiter = max(0, spec.budget // pop - 1)
    gen = {"n": 0}

    def mapper(func: Callable, xs: Any) -> list[float]:
        xs = list(xs)
        got = ev.ask([(box.to_params(x), "de") for x in xs], gen["n"])
        gen["n"] += 1
        return [(-e.f if e is not None and math.isfinite(e.f) else 0.0) for e in got]

    x0 = box.to_unit(cands[0]) if cands else None
    differential_evolution(lambda x: 0.0, [(0.0, 1.0)] * box.d, maxiter=maxiter, popsize=spec.search.popsize,
                           rng=np.random.default_rng(spec.seed), polish=False, init="latinhypercube",
                           updating="deferred", workers=mapper, tol=0.0, atol=0.0, x0=x0)
    return {"locals": [], "iterations": gen["n"]}


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


def _confirm(ev: _Evaluator, spec: OptimizeSpec, path: Path, n_jobs: int, solve_fn: Callable | None
             ) -> tuple[_Eval | None, dict | None, list, list[dict]]:
    """Re-solve the best feasible designs on the finer mesh until one holds."""
    from snapjump_cli.sweep import run_sweep

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
        scored = _objective_values(_read_cache(path, set(keys)), spec.objective, spec.jump)
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
        Injected solver (see :func:`snapjump_cli.sweep.run_sweep`).
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
    box = _Box(spec.bounds)
    cands: list[tuple[float, ...]] = []
    baseline, base_design = math.nan, None
    if from_df is not None:
        cands, baseline, base_design = _candidates_from(from_df, box, spec)
        if not cands:
            log.warning("--from: no feasible row lies inside the box; starting from an initial sample")
        if "mesh_nt" in from_df.columns and len(from_df):
            m = spec.sweep.mesh
            same = ((from_df["mesh_order"] == m.order) & (from_df["mesh_nt"] == m.nt)
                    & np.isclose(from_df["mesh_aspect"].astype(float), m.aspect)).fillna(False).all()
            if not same:
                log.warning("--from rows were solved on another mesh than the spec's %s: their values "
                            "(the baseline) are not exactly comparable", m)
    ev = _Evaluator(spec, evals_path, n_jobs, spec.budget, solve_fn, warm_up_fn, on_batch)
    if spec.method == "pattern":
        info = _pattern_search(ev, box, spec, cands)
    else:
        info = _differential_evolution(ev, box, spec, cands)

    result = OptimizeResult(table=pd.DataFrame(), spec=spec, iterations=info["iterations"])
    result.n_evaluations = ev.n_solves
    result.n_invalid = sum(1 for e in ev.evals if not e.valid)
    result.n_resumed = ev.n_resumed
    if from_df is None or not math.isfinite(baseline):  # the best of the start points
        starts = [e for e in ev.evals if e.stage in ("start", "init") and e.row is not None
                  and np.isfinite(float(e.row.get("y_jump_m") or np.nan)) and math.isfinite(e.f)]
        if starts:
            b = max(starts, key=lambda e: (float(e.row["y_jump_m"]), -e.number))
            baseline, base_design = float(b.row["y_jump_m"]), b.params
    result.baseline_y_jump_m, result.baseline_design = baseline, base_design

    chosen: _Eval | None = None
    confirm_rows: list[dict] = []
    if spec.confirm.enabled and ev.best() is not None:
        chosen, crow, tried, confirm_rows = _confirm(ev, spec, confirm_path, n_jobs, solve_fn)
        result.confirm_tried = tried
        result.confirm_mesh = finer_mesh(spec.sweep.mesh)
        if chosen is not None:
            result.confirmed = True
            result.confirm_row = crow
            result.y_jump_confirmed_m = float(crow["y_jump_m"])
    elif not spec.confirm.enabled:
        chosen = ev.best()
    if chosen is not None:
        r = chosen.row
        result.best = dict(zip(PARAMETERS, chosen.params))
        result.best_row = r
        result.objective_value = chosen.f
        for k in ("y_jump_m", "dE_J", "dy_pole_m", "h_imp_m"):
            setattr(result, k, float(r[k]))
        # its path and the last poll around it
        owner = None
        for lc in info["locals"]:
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
    from snapjump_cli import results as res

    df = res.rows_to_table(rows).to_pandas(types_mapper=res.pandas_types_mapper())
    df["iteration"] = pd.array([int(r.get("iteration", 0)) for r in rows], dtype="Int64")
    df["stage"] = pd.array([str(r.get("stage", "")) for r in rows], dtype="string")
    return df


def write_result(result: OptimizeResult, output: str | Path, extra_meta: Mapping[str, Any] | None = None) -> Path:
    """Write the evaluation table atomically, with provenance and the summary in its metadata."""
    from snapjump_cli import results as res

    meta = res.provenance(result.spec.to_dict(), command="optimize", summary=result.summary(), **dict(extra_meta or {}))
    return res.write_frame_atomic(result.table, output, meta)


# ---- plots ---------------------------------------------------------------------------------------
def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _save_atomic(fig: Any, path: Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".png", dir=path.parent)
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=150)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


_STAGE_COLOURS = {"start": "#1f77b4", "init": "#17becf", "poll": "#7f7f7f", "pattern": "#ff7f0e", "cross": "#bcbd22",
                  "model": "#e377c2",
                  "de": "#9467bd"}


def _scale(objective: str) -> tuple[float, str]:
    return (1e3, "y_jump [mm]") if objective == "y_jump_m" else (1e3, "dE [mJ]")


def plot_progress(result: OptimizeResult, path: str | Path) -> Path:
    """The objective of every evaluation against its number (infeasible ones at the bottom), the
    running best, the baseline and the confirmed value. Writes a PNG atomically."""
    plt = _pyplot()
    objective = result.spec.objective
    sc, label = _scale(objective)
    t = result.table
    t = t[t["stage"] != "confirm"].reset_index(drop=True)
    scored = _objective_values(t, objective, result.spec.jump) if len(t) else t.assign(_f=[])
    f = scored["_f"].to_numpy(dtype=float) * sc
    valid = (t["status"] != "invalid_geometry").to_numpy(dtype=bool)
    n = np.arange(len(t))
    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    try:
        stages = t["stage"].astype(str).to_numpy()
        for st, colour in _STAGE_COLOURS.items():
            m = (stages == st) & np.isfinite(f)
            if m.any():
                big = st in ("model", "start")
                ax.scatter(n[m], f[m], s=40 if big else 10, marker="*" if st == "model" else "o", color=colour,
                           label=st, alpha=0.9 if big else 0.7, zorder=3 if big else 2)
        bad = valid & ~np.isfinite(f)
        fin = f[np.isfinite(f)]
        floor = (np.nanmin(fin) if fin.size else 0.0)
        if bad.any():
            ax.scatter(n[bad], np.full(bad.sum(), floor), marker="x", s=14, color="#d62728",
                       label="no snap / failed / mesh-sensitive")
        if fin.size:
            run = np.fmax.accumulate(np.where(np.isfinite(f), f, -np.inf))
            run[~np.isfinite(run)] = np.nan
            ax.step(n, run, where="post", color="k", lw=1.2, label="best so far")
        if objective == "y_jump_m" and math.isfinite(result.baseline_y_jump_m):
            ax.axhline(result.baseline_y_jump_m * sc, color="#2ca02c", ls="--", lw=1, label="baseline")
        if objective == "y_jump_m" and math.isfinite(result.y_jump_confirmed_m):
            ax.axhline(result.y_jump_confirmed_m * sc, color="#7b3294", ls=":", lw=1.2, label="confirmed (finer mesh)")
        if fin.size:
            top = np.nanmax(fin)
            ax.set_ylim(max(floor, top - 0.5 * abs(top)) - 0.02 * abs(top), top + 0.05 * abs(top))
        ax.set_xlabel("evaluation number (every design asked, invalid geometries included)")
        ax.set_ylabel(label)
        ax.set_title(f"snapjump optimize ({result.spec.method}, seed {result.spec.seed}): "
                     f"{result.n_evaluations} solves")
        ax.legend(loc="lower right", fontsize=7)
        return _save_atomic(fig, Path(path))
    finally:
        plt.close(fig)


def plot_path(result: OptimizeResult, path: str | Path) -> Path:
    """The chosen design's path through parameter space: each free parameter of its successive
    incumbents against the evaluation number, within the box. Writes a PNG atomically."""
    plt = _pyplot()
    free = [p for p in PARAMETERS if result.spec.bounds[p][0] < result.spec.bounds[p][1]]
    steps = result.path
    sc, label = _scale(result.spec.objective)
    n = len(free) + 1
    fig, axes = plt.subplots(n, 1, figsize=(6, 1.5 * n + 0.6), sharex=True, constrained_layout=True)
    axes = np.atleast_1d(axes)
    try:
        x = [s["evaluation"] for s in steps]
        for ax, p in zip(axes, free):
            lo, hi = result.spec.bounds[p]
            v = [s[p] for s in steps]
            ax.plot(x, v, "o-", ms=3, color="#1f77b4")
            ax.axhline(lo, color="0.6", ls="--", lw=0.8)
            ax.axhline(hi, color="0.6", ls="--", lw=0.8)
            if result.baseline_design is not None:
                ax.axhline(dict(zip(PARAMETERS, result.baseline_design))[p], color="#2ca02c", ls=":", lw=0.8)
            ax.set_ylabel(f"{p}\n[{lo:g}, {hi:g}]", fontsize=8)
            # zoom on the path (at least a quarter of the box), never beyond the box
            half = max(0.125 * (hi - lo), 0.6 * (max(v) - min(v)) if v else 0.0)
            mid = 0.5 * (max(v) + min(v)) if v else 0.5 * (lo + hi)
            pad = 0.03 * (hi - lo)
            ax.set_ylim(max(lo - pad, mid - half), min(hi + pad, mid + half))
        axes[-1].plot(x, [s["objective"] * sc for s in steps], "o-", ms=3, color="k")
        axes[-1].set_ylabel(label, fontsize=8)
        axes[-1].set_xlabel("evaluation number")
        fixed = ", ".join(f"{p} = {result.spec.bounds[p][0]:g}" for p in PARAMETERS if p not in free)
        axes[0].set_title("path of the chosen design (box: dashed, baseline: dotted)" + (f"\nfixed: {fixed}" if fixed else ""),
                          fontsize=9)
        return _save_atomic(fig, Path(path))
    finally:
        plt.close(fig)


def make_plots(result: OptimizeResult, output: str | Path) -> list[Path]:
    """Both plots next to ``output``: ``<stem>.progress.png`` and ``<stem>.path.png``."""
    output = Path(output)
    stem = output.name.removesuffix(".parquet")
    files = [plot_progress(result, output.with_name(stem + ".progress.png"))]
    if result.path:
        files.append(plot_path(result, output.with_name(stem + ".path.png")))
    return files
