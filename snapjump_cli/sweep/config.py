"""Sweep configuration: a YAML grid spec validated against a hand-written schema.

The file is read with :func:`snapjump_cli.sweep.checks.read_yaml` (safe YAML; a key given twice,
or a file over 4 MB, is an error). Only ``grid:`` is required; every other key has a
default. Unknown keys are rejected. Every error is a :class:`ConfigError` whose message names the
file, the key path (``grid.eta_i.num``) and what was expected, e.g.::

    configs/bad.yaml: grid.eta_i.num: expected an integer >= 1, got 0

Schema (defaults in brackets)::

    grid:                      # the designs are the Cartesian product of the five axes
      eta_i:    AXIS           # R_i / t_i
      theta_i:  AXIS           # inner polar angle [deg], in (0, 180)
      eta_o:    AXIS           # R_o / t_o
      theta_o:  AXIS           # outer polar angle [deg], in (0, 180)
      mu_ratio: AXIS           # mu_i / mu_o
    points: POINTS             # instead of grid: an explicit list of designs
    R_i: 0.03                  # inner-cap mid-surface radius [m]
    materials: {mu_i: 0.35e+6, J_m: 24}          # [Pa], Gent locking parameter
    ring: {t_ring_frac: 1/30, w_ring_frac: 1/10} # ring size as fractions of R_i
    mesh: {order: 2, nt: 4, aspect: 2.0}         # fields of MeshSettings
    solver: {tol: 1e-9, ...}                     # fields of SolverSettings
    fluid: water               # or {kind: air, V0_ml: 45, gamma: 1, p0: 101325} (FluidSettings)
    output: results/<config stem>.parquet        # relative paths are relative to the working dir
    n_jobs: -1                 # joblib n_jobs (-1: all cores)
    chunk_size: 16             # results per part file (see snapjump_cli.sweep.run)

Exactly one of ``grid:`` and ``points:`` is given. ``POINTS`` is either a non-empty list of
mappings ``{eta_i, theta_i, eta_o, theta_o, mu_ratio}`` (angles in degrees, as on the grid axes) or
the path of a CSV or parquet file with those columns (``theta_i_deg`` / ``theta_o_deg`` are accepted
for the angles, so a result file can be fed back; other columns are ignored); a relative path is
relative to the YAML file's folder.

where ``AXIS`` is either a non-empty list of distinct numbers or a mapping ``{start, stop, num}``
(``numpy.linspace(start, stop, num)``, ``start <= stop``, integer ``num >= 1``; ``num = 1`` needs
``start == stop``).

Numbers may also be written as strings that parse as a finite float: PyYAML (YAML 1.1) reads
``0.35e6`` (no sign in the exponent) as the *string* ``"0.35e6"``, which is accepted here; so is a
simple fraction ``a/b`` such as ``1/30``.
"""
from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping

import numpy as np

from snapjump_cli.fe.axisym.fluid import FLUID_KEYS, WATER, FluidSettings, fluid_from_mapping
from snapjump_cli.geometry.caps import J_M_DEFAULT, MU_ELITE_DOUBLE_32, R_I_DEFAULT, RADIUS_RANGE_M
from snapjump_cli.settings import MeshSettings, SettingsError, SolverSettings
from snapjump_cli.sweep.checks import CheckContext, ConfigError, read_yaml, regular_input, warn_if_radians

__all__ = [
    "ConfigError",
    "GRID_AXES",
    "MAX_DESIGNS",
    "SweepConfig",
    "DesignPoint",
    "load_config",
    "read_yaml",
    "parse_config",
]

#: The grid axes, in the order of the Cartesian product (the last one varies fastest).
GRID_AXES: tuple[str, ...] = ("eta_i", "theta_i", "eta_o", "theta_o", "mu_ratio")

_AXIS_EXPECTED = "a non-empty list of numbers or a mapping {start, stop, num}"
_DEFAULT_CHUNK = 16
#: Largest sweep run without being asked explicitly (``max_designs`` / ``--max-designs``): a grid's
#: size is computed from its ``num`` values before any axis is built, a point list's before its
#: points are checked.
MAX_DESIGNS = 100_000


@dataclass(frozen=True)
class DesignPoint:
    """One point of the grid: the inputs of :class:`snapjump_cli.geometry.caps.Design`.

    Angles in degrees. ``index`` is the position in the Cartesian product.
    """

    index: int
    eta_i: float
    theta_i_deg: float
    eta_o: float
    theta_o_deg: float
    mu_ratio: float
    R_i: float
    mu_i: float
    J_m: float
    t_ring_frac: float
    w_ring_frac: float

    def design_kwargs(self) -> dict[str, float]:
        """Keyword arguments for :class:`~snapjump_cli.geometry.caps.Design`."""
        d = dataclasses.asdict(self)
        d.pop("index")
        return d


@dataclass(frozen=True)
class SweepConfig:
    """A validated sweep configuration (all defaults applied).

    Attributes
    ----------
    grid : dict
        Axis name (one of :data:`GRID_AXES`) -> tuple of float values (empty tuples with ``points``).
    points : tuple or None
        An explicit list of designs instead of the grid: tuples of the five values in the order
        of :data:`GRID_AXES` (angles in degrees).
    R_i, mu_i, J_m, t_ring_frac, w_ring_frac : float
        Fixed design parameters shared by every grid point.
    mesh, solver : MeshSettings, SolverSettings
    output : pathlib.Path
        Default result file (the CLI's ``-o`` overrides it).
    n_jobs : int
        joblib ``n_jobs`` (``-1``: all cores; never 0).
    chunk_size : int
        Number of finished designs written per part file.
    source : str
        Where the config came from (file path, or ``"<dict>"``).
    raw : dict
        The document as read (for provenance).
    """

    grid: dict[str, tuple[float, ...]]
    R_i: float = R_I_DEFAULT
    mu_i: float = MU_ELITE_DOUBLE_32
    J_m: float = J_M_DEFAULT
    t_ring_frac: float = 1.0 / 30.0
    w_ring_frac: float = 1.0 / 10.0
    mesh: MeshSettings = field(default_factory=MeshSettings)
    solver: SolverSettings = field(default_factory=SolverSettings)
    output: Path = Path("results/sweep.parquet")
    n_jobs: int = -1
    chunk_size: int = _DEFAULT_CHUNK
    source: str = "<dict>"
    raw: dict = field(default_factory=dict, compare=False)
    points: tuple[tuple[float, float, float, float, float], ...] | None = None
    fluid: FluidSettings = WATER

    @property
    def n_designs(self) -> int:
        """Number of designs (the size of the Cartesian product, or of the point list)."""
        if self.points is not None:
            return len(self.points)
        return math.prod(len(self.grid[a]) for a in GRID_AXES)

    def designs(self) -> Iterator[DesignPoint]:
        """Iterate over the designs in a fixed order (grid: ``mu_ratio`` varies fastest; points:
        in the order given)."""
        if self.points is not None:
            values: Iterator = iter(self.points)
        else:
            values = itertools.product(*[self.grid[a] for a in GRID_AXES])
        for i, (ei, ti, eo, to, mr) in enumerate(values):
            yield DesignPoint(
                index=i, eta_i=ei, theta_i_deg=ti, eta_o=eo, theta_o_deg=to, mu_ratio=mr,
                R_i=self.R_i, mu_i=self.mu_i, J_m=self.J_m,
                t_ring_frac=self.t_ring_frac, w_ring_frac=self.w_ring_frac,
            )

    def replace(self, **changes: Any) -> "SweepConfig":
        """A copy with some fields replaced (e.g. ``output`` or ``n_jobs`` from the CLI)."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """The resolved configuration as plain JSON-able data (explicit grid values)."""
        out = {
            "grid": {a: list(self.grid[a]) for a in GRID_AXES},
            "R_i": self.R_i,
            "materials": {"mu_i": self.mu_i, "J_m": self.J_m},
            "ring": {"t_ring_frac": self.t_ring_frac, "w_ring_frac": self.w_ring_frac},
            "mesh": self.mesh.as_dict(),
            "solver": self.solver.as_dict(),
            "output": str(self.output),
            "n_jobs": self.n_jobs,
            "chunk_size": self.chunk_size,
            "source": self.source,
            "n_designs": self.n_designs,
        }
        if self.points is not None:
            del out["grid"]
            out["points"] = [dict(zip(GRID_AXES, p)) for p in self.points]
        if self.fluid.is_air:  # (a water config's dict is as it was before the setting existed)
            out["fluid"] = self.fluid.as_dict()
        return out


# ---- schema ----------------------------------------------------------------------------------
#: The keys a sweep config shares with an optimisation spec (:mod:`snapjump_cli.optimize.spec`).
COMMON_KEYS: dict[str, str] = {
    "R_i": "the inner-cap radius in metres (> 0)",
    "materials": "a mapping {mu_i, J_m}",
    "ring": "a mapping {t_ring_frac, w_ring_frac}",
    "mesh": "a mapping of mesh settings",
    "solver": "a mapping of solver settings",
    "output": "the result file path",
    "n_jobs": "the number of parallel jobs",
    "chunk_size": "the number of results per part file",
}
_TOP_KEYS: dict[str, str] = {
    "grid": "a mapping with keys " + ", ".join(GRID_AXES),
    "points": "a list of designs {" + ", ".join(GRID_AXES) + "} or a CSV/parquet file of them",
    **COMMON_KEYS,
    "fluid": "water or a mapping {kind: air, V0_ml, gamma, p0}",
}
_GRID_KEYS: dict[str, str] = {a: _AXIS_EXPECTED for a in GRID_AXES}
_RANGE_KEYS: dict[str, str] = {"start": "a number", "stop": "a number", "num": "an integer >= 1"}


def axis_check(name: str) -> tuple[Callable[[float], bool], str]:
    if name.startswith("theta"):
        return (lambda x: 0.0 < x < 180.0), "a number of degrees in (0, 180)"
    return (lambda x: x > 0.0), "a finite number > 0"


def _axis_size(ctx: CheckContext, name: str, value: Any) -> int:
    """The number of values of a grid axis, read from ``num`` or the list's length (nothing built)."""
    if isinstance(value, Mapping) and "num" in value:
        return ctx.integer(f"grid.{name}.num", value["num"], minimum=1)
    return len(value) if isinstance(value, (list, tuple)) else 1


def _too_many(ctx: CheckContext, path: str, n: int, max_designs: int, what: str) -> ConfigError:
    return ConfigError(ctx.source, path, f"{what}{n} designs exceed the limit of {max_designs}; check it, or raise "
                                         f"the limit with --max-designs")


def _parse_axis(ctx: CheckContext, name: str, value: Any) -> tuple[float, ...]:
    path = f"grid.{name}"
    ok, expected = axis_check(name)
    if isinstance(value, Mapping):
        m = ctx.mapping(path, value, _RANGE_KEYS, required=("start", "stop", "num"))
        start = ctx.number(f"{path}.start", m["start"], expected)
        stop = ctx.number(f"{path}.stop", m["stop"], expected)
        num = ctx.integer(f"{path}.num", m["num"], minimum=1)
        for k, x in (("start", start), ("stop", stop)):
            if not ok(x):
                raise ctx.fail(f"{path}.{k}", expected, m[k])
        if start > stop:
            raise ConfigError(ctx.source, f"{path}.stop", f"expected stop >= start = {start:g}, got {stop:g}")
        if num == 1 and start != stop:
            raise ConfigError(ctx.source, f"{path}.num", f"expected num >= 2 when start != stop ({start:g} != {stop:g}), got 1")
        values = tuple(float(x) for x in np.linspace(start, stop, num))
        if num > 1 and len(set(values)) != num:
            raise ConfigError(ctx.source, f"{path}.num", f"expected distinct grid values, got duplicates for num = {num}")
        return values
    if isinstance(value, (list, tuple)):
        if not value:
            raise ConfigError(ctx.source, path, f"expected {_AXIS_EXPECTED}, got an empty list")
        values = []
        for j, v in enumerate(value):
            x = ctx.number(f"{path}[{j}]", v, expected)
            if not ok(x):
                raise ctx.fail(f"{path}[{j}]", expected, v)
            if x in values:
                raise ConfigError(ctx.source, f"{path}[{j}]", f"expected distinct values, got {v!r} twice")
            values.append(x)
        return tuple(values)
    raise ctx.fail(path, _AXIS_EXPECTED, value)


_POINT_KEYS: dict[str, str] = {a: axis_check(a)[1] for a in GRID_AXES}
_POINTS_EXPECTED = "a non-empty list of mappings {" + ", ".join(GRID_AXES) + "} or a CSV/parquet file path"


def _read_points_file(ctx: CheckContext, value: str, max_designs: int = MAX_DESIGNS) -> list[dict]:
    """Rows of a CSV or parquet file of designs as dicts keyed by :data:`GRID_AXES` (a file of more
    than ``max_designs`` rows is refused before it is parsed)."""
    import pandas as pd

    path = Path(value)
    if not path.is_absolute() and not ctx.source.startswith("<"):
        path = Path(ctx.source).parent / path
    regular_input(ctx.source, path, "points")  # a FIFO or a device would be read for ever
    try:
        if path.suffix.lower() == ".csv":
            with open(path, "rb") as fh:  # lines counted (fast) before the file is parsed
                n = sum(block.count(b"\n") for block in iter(lambda: fh.read(1 << 20), b""))
            if n - 1 > max_designs:
                raise _too_many(ctx, "points", n - 1, max_designs, f"{path}: about ")
            df = pd.read_csv(path)
        elif path.suffix.lower() in (".parquet", ".pq"):
            import pyarrow.parquet as pq

            if (n := pq.ParquetFile(path).metadata.num_rows) > max_designs:
                raise _too_many(ctx, "points", n, max_designs, f"{path}: ")
            df = pd.read_parquet(path, use_threads=False)  # as snapjump_cli.sweep.results.ARROW_THREADS
        else:
            raise ctx.fail("points", "a .csv or .parquet file", value)
    except ConfigError:
        raise
    except FileNotFoundError:
        raise ConfigError(ctx.source, "points", f"file not found: {path}") from None
    except Exception as e:  # unreadable or malformed table
        raise ConfigError(ctx.source, "points", f"cannot read {path} ({type(e).__name__}: {e})") from None
    cols = {}
    for a in GRID_AXES:
        for c in (a, f"{a}_deg"):
            if c in df.columns:
                cols[a] = c
                break
        else:
            raise ConfigError(ctx.source, "points", f"{path}: missing column {a!r} (have: {', '.join(map(str, df.columns))})")
    if len(df) == 0:
        raise ConfigError(ctx.source, "points", f"{path}: no rows")
    return [{a: row[cols[a]] for a in GRID_AXES} for row in df.to_dict("records")]


def _parse_points(ctx: CheckContext, value: Any, max_designs: int = MAX_DESIGNS) -> tuple[tuple[float, ...], ...]:
    if isinstance(value, str) and value.strip():
        rows = _read_points_file(ctx, value.strip(), max_designs)
        where = lambda j: f"points (row {j} of {value})"  # noqa: E731
    elif isinstance(value, (list, tuple)) and value:
        rows = list(value)
        where = lambda j: f"points[{j}]"  # noqa: E731
    else:
        raise ctx.fail("points", _POINTS_EXPECTED, value)
    if len(rows) > max_designs:
        raise _too_many(ctx, "points", len(rows), max_designs, "")
    out = []
    first: dict[tuple[float, ...], int] = {}
    for j, row in enumerate(rows):
        m = ctx.mapping(where(j), row, _POINT_KEYS, required=GRID_AXES)
        vals = []
        for a in GRID_AXES:
            ok, expected = axis_check(a)
            x = ctx.number(f"{where(j)}.{a}", m[a], expected)
            if not ok(x):
                raise ctx.fail(f"{where(j)}.{a}", expected, m[a])
            vals.append(x)
        t = tuple(vals)
        if t in first:  # one design named twice would be solved and counted once: say so
            raise ConfigError(ctx.source, where(j), f"the same design as {where(first[t])}; give each design once "
                                                    f"(as the grid's axes are)")
        first[t] = j
        out.append(t)
    return tuple(out)


def _settings_from(ctx: CheckContext, path: str, value: Any, cls: type) -> Any:
    """Build a settings dataclass, typing each field after its default value; the ranges are
    checked by the settings class itself (the same for YAML and the command line)."""
    defaults = cls()
    names = [f.name for f in dataclasses.fields(cls)]
    if value is None:
        return defaults
    m = ctx.mapping(path, value, {n: n for n in names})
    kwargs = {}
    for k, v in m.items():
        kp = f"{path}.{k}"
        d = getattr(defaults, k)
        if isinstance(d, bool):
            x = ctx.boolean(kp, v)
        elif isinstance(d, int):
            x = ctx.integer(kp, v)
        elif isinstance(d, float):
            x = ctx.number(kp, v)
        else:  # pragma: no cover - settings only hold bools and numbers today
            x = v
        kwargs[k] = x
    try:
        return cls(**kwargs)
    except SettingsError as e:
        raise ctx.fail(f"{path}.{e.field}", e.expected, m.get(e.field, e.value)) from None


def _parse_fluid(ctx: CheckContext, value: Any) -> FluidSettings:
    """The ``fluid:`` setting (the checks are :class:`snapjump_cli.fe.axisym.fluid.FluidSettings`'s, as on the
    command line)."""
    if isinstance(value, Mapping):
        ctx.mapping("fluid", value, FLUID_KEYS)
    try:
        return fluid_from_mapping(value, number=lambda k, v: ctx.number(f"fluid.{k}", v, FLUID_KEYS[k]))
    except SettingsError as e:
        where = f"fluid.{e.field}" if isinstance(value, Mapping) else "fluid"
        raise ctx.fail(where, e.expected, value.get(e.field, e.value) if isinstance(value, Mapping) else value) from None


def parse_config(doc: Any, source: str = "<dict>", max_designs: int = MAX_DESIGNS) -> SweepConfig:
    """Validate a loaded YAML document and apply the defaults.

    Parameters
    ----------
    doc
        The object returned by :func:`yaml.safe_load`.
    source
        Name used in error messages (usually the file path).
    max_designs
        Refuse more designs than this, counted before the grid's axes or the points are built.

    Returns
    -------
    SweepConfig

    Raises
    ------
    ConfigError
        On the first schema violation, naming ``source``, the key path and what was expected.
    """
    ctx = CheckContext(source)
    if doc is None:
        raise ConfigError(source, "grid", "missing required key (the file is empty); expected " + _TOP_KEYS["grid"])
    top = ctx.mapping("", doc, _TOP_KEYS)
    if "grid" in top and "points" in top:
        raise ConfigError(source, "points", "give either grid: or points:, not both")
    kw: dict[str, Any] = {"source": source, "raw": dict(top)}
    if "points" in top:
        kw["points"] = _parse_points(ctx, top["points"], max_designs)
        for j, a in enumerate(GRID_AXES):
            if a.startswith("theta"):
                warn_if_radians(source, f"points (column {a})", [p[j] for p in kw["points"]])
        kw["grid"] = {a: () for a in GRID_AXES}
    elif "grid" not in top:
        raise ConfigError(source, "grid", "missing required key; expected " + _TOP_KEYS["grid"] + " (or points:)")
    else:
        g = ctx.mapping("grid", top["grid"], _GRID_KEYS, required=GRID_AXES)
        sizes = [_axis_size(ctx, a, g[a]) for a in GRID_AXES]
        if math.prod(sizes) > max_designs:
            raise _too_many(ctx, "grid", math.prod(sizes), max_designs, " x ".join(map(str, sizes)) + " = ")
        kw["grid"] = {a: _parse_axis(ctx, a, g[a]) for a in GRID_AXES}
        for a in ("theta_i", "theta_o"):
            warn_if_radians(source, f"grid.{a}", kw["grid"][a])

    if "R_i" in top:
        kw["R_i"] = ctx.positive("R_i", top["R_i"])
        lo, hi = RADIUS_RANGE_M
        if not lo <= kw["R_i"] <= hi:
            raise ctx.fail("R_i", f"a radius in [{lo:g}, {hi:g}] m", top["R_i"])
    if top.get("materials") is not None:
        m = ctx.mapping("materials", top["materials"], {"mu_i": "the inner shear modulus [Pa]", "J_m": "the Gent parameter"})
        for k in m:
            kw[k] = ctx.positive(f"materials.{k}", m[k])
    if top.get("ring") is not None:
        r = ctx.mapping("ring", top["ring"], {"t_ring_frac": "t_ring / R_i", "w_ring_frac": "w_ring / R_i"})
        for k in r:
            kw[k] = ctx.positive(f"ring.{k}", r[k])
    kw["mesh"] = _settings_from(ctx, "mesh", top.get("mesh"), MeshSettings)
    kw["solver"] = _settings_from(ctx, "solver", top.get("solver"), SolverSettings)
    if top.get("fluid") is not None:
        kw["fluid"] = _parse_fluid(ctx, top["fluid"])
        if kw["fluid"].is_air and kw["solver"].harmonics > 0:
            raise ConfigError(source, "solver.harmonics", "the harmonic check is not available with fluid: air; "
                              f"expected 0, got {kw['solver'].harmonics}")
    stem = Path(source).stem if source and not source.startswith("<") else "sweep"
    kw["output"] = Path("results") / f"{stem}.parquet"
    if top.get("output") is not None:
        out = top["output"]
        if not isinstance(out, str) or not out.strip():
            raise ctx.fail("output", "a file path (string)", out)
        kw["output"] = Path(out)
    if top.get("n_jobs") is not None:
        kw["n_jobs"] = ctx.integer("n_jobs", top["n_jobs"], nonzero=True)
    if top.get("chunk_size") is not None:
        kw["chunk_size"] = ctx.integer("chunk_size", top["chunk_size"], minimum=1, maximum=MAX_DESIGNS)
    return SweepConfig(**kw)


def load_config(path: str | Path, max_designs: int = MAX_DESIGNS) -> SweepConfig:
    """Read and validate a sweep config file.

    Parameters
    ----------
    path
        A YAML file (see the module docstring for the schema).
    max_designs
        See :func:`parse_config`.

    Returns
    -------
    SweepConfig

    Raises
    ------
    ConfigError
        The file is missing or unreadable, is not valid YAML, or does not match the schema.
    """
    source = str(path)
    return parse_config(read_yaml(path), source, max_designs)
