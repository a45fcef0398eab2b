"""The optimisation spec (``snapjump optimize SPEC.yaml``): schema, validation and input files.

:func:`load_spec` / :func:`parse_spec` validate a spec like a sweep config (every error is a
:class:`~snapjump_cli.sweep.config.ConfigError` naming the file and the key path; the schema is in the
docstring of :mod:`snapjump_cli.optimize.run`); :func:`read_from` reads the ``--from`` rows;
:func:`cache_paths` and :func:`check_cache` name and guard the evaluation caches.
"""
from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import pandas as pd

from snapjump_cli.sweep.config import (
    GRID_AXES,
    MAX_DESIGNS,
    ConfigError,
    SweepConfig,
    axis_check,
    COMMON_KEYS,
    CheckContext,
    parse_config,
    read_yaml,
)
from snapjump_cli.sweep.checks import warn_if_radians
from snapjump_cli.jump import JumpParams
from snapjump_cli.settings import MeshSettings, without_limits

log = logging.getLogger("snapjump_cli.optimize.run")

#: The five design parameters, in the order of :data:`snapjump_cli.sweep.config.GRID_AXES`, and their
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
#: Most solves of one run (``budget``, ``--budget``; also the bound of ``search.starts``, ``init``,
#: ``popsize`` and ``confirm.candidates``): the sweep's design limit.
MAX_BUDGET = MAX_DESIGNS
SIG_DIGITS = 10  # design parameters are rounded to this many significant digits (stable keys)

_TOP_KEYS: dict[str, str] = {
    "bounds": "a mapping with keys " + ", ".join(PARAMETERS),
    "objective": "one of " + ", ".join(OBJECTIVES),
    "budget": f"the number of solves (an integer in [1, {MAX_DESIGNS}])",
    "seed": "an integer >= 0",
    "method": "one of " + ", ".join(METHODS),
    "search": "a mapping {starts, init, step, min_step, spread, popsize, poll, model, model_step}",
    "confirm": "a mapping {tolerance, candidates} or false",
    "jump": "a mapping {rho, c_d, alpha}",
    **COMMON_KEYS,  # as in a sweep config
}
#: Keys handed to :func:`snapjump_cli.sweep.config.parse_config` (validated exactly as in a sweep).
_SWEEP_KEYS = tuple(COMMON_KEYS)
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


def _parse_bound(ctx: CheckContext, name: str, value: Any) -> tuple[float, float]:
    path = f"bounds.{name}"
    ok, expected = axis_check(name)
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


def _choice(ctx: CheckContext, path: str, value: Any, options: Sequence[str]) -> str:
    if not isinstance(value, str) or value not in options:
        raise ctx.fail(path, "one of " + ", ".join(options), value)
    return value


def parse_spec(doc: Any, source: str = "<dict>") -> OptimizeSpec:
    """Validate a loaded optimisation spec and apply the defaults.

    Parameters
    ----------
    doc
        The spec as plain data (e.g. from :func:`snapjump_cli.sweep.config.read_yaml`).
    source
        The name (usually the file path) that error messages give.

    Returns
    -------
    OptimizeSpec
        The spec with every default applied.

    Raises
    ------
    ConfigError
        On the first violation, naming ``source``, the key path and what was expected.
    """
    ctx = CheckContext(source)
    if doc is None:
        raise ConfigError(source, "bounds", "missing required key (the file is empty); expected " + _TOP_KEYS["bounds"])
    top = ctx.mapping("", doc, _TOP_KEYS, required=("bounds",))
    b = ctx.mapping("bounds", top["bounds"], {p: _BOUND_EXPECTED for p in PARAMETERS}, required=PARAMETERS)
    bounds = {p: _parse_bound(ctx, p, b[p]) for p in PARAMETERS}
    for a in ("theta_i", "theta_o"):
        warn_if_radians(source, f"bounds.{a}", sorted(set(bounds[a])))
    if all(lo == hi for lo, hi in bounds.values()):
        raise ConfigError(source, "bounds", "expected at least one free parameter ([lo, hi] with lo < hi), got all fixed")
    kw: dict[str, Any] = {"bounds": bounds, "source": source, "raw": dict(top)}
    if top.get("objective") is not None:
        kw["objective"] = _choice(ctx, "objective", top["objective"], OBJECTIVES)
    if top.get("method") is not None:
        kw["method"] = _choice(ctx, "method", top["method"], METHODS)
    if top.get("budget") is not None:
        kw["budget"] = ctx.integer("budget", top["budget"], minimum=1, maximum=MAX_BUDGET)
    if top.get("seed") is not None:
        kw["seed"] = ctx.integer("seed", top["seed"], minimum=0)

    if top.get("search") is not None:
        s = ctx.mapping("search", top["search"], _SEARCH_KEYS)
        skw: dict[str, Any] = {}
        for k in ("starts", "init"):
            if k in s:
                skw[k] = ctx.integer(f"search.{k}", s[k], minimum=1, maximum=MAX_BUDGET)
        if "popsize" in s:
            skw["popsize"] = ctx.integer("search.popsize", s["popsize"], minimum=2, maximum=MAX_BUDGET)
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
                ckw["candidates"] = ctx.integer("confirm.candidates", c["candidates"], minimum=1, maximum=MAX_BUDGET)
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
    return parse_spec(read_yaml(path), str(path))


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


_CACHE_SETTINGS = ("mesh", "solver", "materials", "ring", "R_i")


def _comparable(key: str, value: Any) -> Any:
    """A setting as compared between runs (the solver's resource limits never change an answer)."""
    return without_limits(value) if key == "solver" else value


def check_cache(path: str | Path, config: SweepConfig) -> None:
    """Refuse a cache file (or its part files) written with other mesh, solver, material or ring
    settings than ``config``'s (one cache holds one setting).

    Raises
    ------
    OptimizeInputError
        Naming the file and what differs.
    """
    from snapjump_cli.sweep import results as res
    from snapjump_cli.sweep.storage import result_files

    path = Path(path)
    files = result_files(path)
    if not files:
        return
    want = config.to_dict()
    for f in files:
        try:
            old = res.read_metadata(f).get("config") or {}
        except Exception as e:  # noqa: BLE001 - not a parquet file
            raise OptimizeInputError(f"{f}: not a readable snapjump result file ({str(e).splitlines()[0]}); "
                                     f"remove it or choose another -o/--output") from None
        diffs = [f"{k} {old.get(k)} -> {want.get(k)}" for k in _CACHE_SETTINGS
                 if k in old and _comparable(k, old.get(k)) != _comparable(k, want.get(k))]
        if diffs:
            raise OptimizeInputError(f"{f}: holds evaluations computed with other settings ({'; '.join(diffs)}); "
                                     f"choose another -o/--output, or remove it to start afresh")



# ---- --from --------------------------------------------------------------------------------------
def read_from(path: str | Path) -> pd.DataFrame:
    """Rows of a sweep (or ranked, or optimize) result: a parquet file, its ``.parts`` folder, or a
    file path whose ``.parts`` folder holds the rows of an unfinished sweep.

    Raises
    ------
    OptimizeInputError
        Nothing readable there, or the columns of a result table are missing.
    """
    from snapjump_cli.sweep import results as res
    from snapjump_cli.sweep.storage import part_files, parts_dir

    path = Path(path)
    if path.is_dir():
        files = part_files(path)
    elif path.exists():
        if not path.is_file():  # a FIFO or a device would block or never end
            raise OptimizeInputError(f"--from: {path}: expected a parquet file, got a special file")
        files = [path]
    else:
        files = part_files(parts_dir(path))
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

