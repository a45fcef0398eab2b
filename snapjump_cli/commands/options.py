"""Click options shared by the commands that take one scene (``mesh``, ``curve``).

A scene is chosen by exactly one selector group:

* ``--design NAME`` (a named design, ``snapjump_cli/geometry/designs.yaml``),
* ``--eta-i --theta-i --eta-o --theta-o [--mu-ratio]`` (an explicit design),
* ``--cap [inner|outer] --theta DEG --eta ETA [--bc ...]`` (a single cap; bare ``--cap`` = inner).

``--radius-mm`` sets R_i (designs) or R (caps). Every bad value becomes :class:`BadInput`
(exit code 2, one line naming the value). Usage::

    @click.command()
    @scene_options
    @mesh_options
    def command(**kw):
        scene = scene_from_options(**pick_scene_options(kw))
        settings = mesh_settings_from_options(**pick_mesh_options(kw))
"""
from __future__ import annotations

import math
from typing import Any, Callable

import click

from snapjump_cli.errors import BadInput
from snapjump_cli.geometry.caps import BASE_CONDITIONS, RADIUS_RANGE_M, CapScene, Design, InvalidDesign
from snapjump_cli.settings import NT_MAX, MeshSettings, SettingsError

__all__ = [
    "FiniteFloat",
    "PositiveInt",
    "SCENE_PARAMS",
    "MESH_PARAMS",
    "scene_options",
    "mesh_options",
    "scene_from_options",
    "mesh_settings_from_options",
    "pick_scene_options",
    "pick_mesh_options",
]

SCENE_PARAMS = ("design", "eta_i", "theta_i", "eta_o", "theta_o", "mu_ratio", "cap", "theta", "eta", "bc", "radius_mm")
MESH_PARAMS = ("order", "nt", "aspect")

_DESIGN_OPTS = ("--eta-i", "--theta-i", "--eta-o", "--theta-o")
_DEFAULT_RADIUS_MM = 30.0


def _opt_name(param: click.Parameter | None) -> str:
    if param is None:
        return "value"
    opts = getattr(param, "opts", None)
    return max(opts, key=len) if opts else str(param.name)


class FiniteFloat(click.ParamType):
    """A float that must be finite (NaN and inf are rejected with a one-line :class:`BadInput`)."""

    name = "float"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> float:
        try:
            x = float(value)
        except (TypeError, ValueError):
            raise BadInput(f"{_opt_name(param)} must be a number, got {value!r}") from None
        if not math.isfinite(x):
            raise BadInput(f"{_opt_name(param)} must be a finite number, got {value!r}")
        return x


class PositiveInt(click.ParamType):
    """An integer >= ``minimum`` (one-line :class:`BadInput` otherwise)."""

    name = "integer"

    def __init__(self, minimum: int = 1, maximum: int | None = None):
        self.minimum, self.maximum = minimum, maximum

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> int:
        if isinstance(value, bool):
            raise BadInput(f"{_opt_name(param)} must be an integer, got {value!r}")
        try:
            n = int(str(value).strip()) if not isinstance(value, int) else value
        except ValueError:
            raise BadInput(f"{_opt_name(param)} must be an integer, got {value!r}") from None
        if n < self.minimum or (self.maximum is not None and n > self.maximum):
            hi = f" and <= {self.maximum}" if self.maximum is not None else ""
            raise BadInput(f"{_opt_name(param)} must be >= {self.minimum}{hi}, got {n}")
        return n


class _Order(click.ParamType):
    name = "1|2"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> int:
        if str(value).strip() in ("1", "2"):
            return int(str(value).strip())
        raise BadInput(f"{_opt_name(param)} must be 1 or 2, got {value!r}")


def _apply(options: list[Callable]) -> Callable[[Callable], Callable]:
    def decorator(f: Callable) -> Callable:
        for opt in reversed(options):
            f = opt(f)
        return f

    return decorator


_F = FiniteFloat()

scene_options = _apply([
    click.option("--design", "design", metavar="NAME", default=None,
                 help="A named design (A, B, C, D, S20b, S20c; snapjump_cli/geometry/designs.yaml)."),
    click.option("--eta-i", "eta_i", type=_F, default=None, help="Explicit design: inner cap R_i/t_i."),
    click.option("--theta-i", "theta_i", type=_F, default=None, metavar="DEG", help="Explicit design: inner cap polar angle [deg]."),
    click.option("--eta-o", "eta_o", type=_F, default=None, help="Explicit design: outer cap R_o/t_o."),
    click.option("--theta-o", "theta_o", type=_F, default=None, metavar="DEG", help="Explicit design: outer cap polar angle [deg]."),
    click.option("--mu-ratio", "mu_ratio", type=_F, default=None, help="Explicit design: mu_i/mu_o (default 1)."),
    click.option("--cap", "cap", type=click.Choice(["inner", "outer"]), is_flag=False, flag_value="inner", default=None,
                 help="A single cap (bare --cap = inner)."),
    click.option("--theta", "theta", type=_F, default=None, metavar="DEG", help="Single cap: polar angle [deg]."),
    click.option("--eta", "eta", type=_F, default=None, help="Single cap: R/t."),
    click.option("--bc", "bc", type=click.Choice(list(BASE_CONDITIONS)), default=None,
                 help="Single inner cap: base condition (default clamped)."),
    click.option("--radius-mm", "radius_mm", type=_F, default=_DEFAULT_RADIUS_MM, show_default=True,
                 help="R_i of a design / R of a single cap [mm]."),
])

_MS = MeshSettings()
mesh_options = _apply([
    click.option("--order", "order", type=_Order(), default=str(_MS.order), show_default=True,
                 help="Element order: 1 (Q4) or 2 (Q9)."),
    click.option("--nt", "nt", type=PositiveInt(1, NT_MAX), default=_MS.nt, show_default=True,
                 help="Elements through each cap's thickness."),
    click.option("--aspect", "aspect", type=_F, default=_MS.aspect, show_default=True,
                 help="Largest element length along an arc / through-thickness size."),
])


def pick_scene_options(kw: dict) -> dict:
    """The scene selector entries of a command's keyword arguments (removed from ``kw``)."""
    return {k: kw.pop(k) for k in SCENE_PARAMS if k in kw}


def pick_mesh_options(kw: dict) -> dict:
    """The mesh option entries of a command's keyword arguments (removed from ``kw``)."""
    return {k: kw.pop(k) for k in MESH_PARAMS if k in kw}


def _finite(name: str, value: Any) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise BadInput(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(x):
        raise BadInput(f"{name} must be a finite number, got {value!r}")
    return x


def scene_from_options(
    design: str | None = None,
    eta_i: float | None = None,
    theta_i: float | None = None,
    eta_o: float | None = None,
    theta_o: float | None = None,
    mu_ratio: float | None = None,
    cap: str | None = None,
    theta: float | None = None,
    eta: float | None = None,
    bc: str | None = None,
    radius_mm: float | None = _DEFAULT_RADIUS_MM,
) -> Design | CapScene:
    """Build the scene chosen by exactly one selector group (see the module docstring).

    Raises :class:`BadInput` (one line naming the value) for a missing or doubled selector, an
    unknown design name, a non-finite number or any :class:`InvalidDesign`.
    """
    groups = {
        "--design": design is not None,
        "--eta-i/--theta-i/--eta-o/--theta-o/--mu-ratio": any(
            v is not None for v in (eta_i, theta_i, eta_o, theta_o, mu_ratio)),
        "--cap/--theta/--eta/--bc": any(v is not None for v in (cap, theta, eta, bc)),
    }
    chosen = [k for k, v in groups.items() if v]
    if not chosen:
        raise BadInput("no scene given: use --design NAME, or --eta-i/--theta-i/--eta-o/--theta-o, "
                       "or --cap [inner|outer] --theta DEG --eta ETA")
    if len(chosen) > 1:
        raise BadInput(f"choose exactly one scene selector, got {' and '.join(chosen)}")
    radius_mm = _finite("--radius-mm", _DEFAULT_RADIUS_MM if radius_mm is None else radius_mm)
    lo, hi = (1e3 * r for r in RADIUS_RANGE_M)
    if not lo <= radius_mm <= hi:
        raise BadInput(f"--radius-mm must lie in [{lo:g}, {hi:g}], got {radius_mm:g}")
    R = radius_mm / 1000.0
    try:
        if design is not None:
            from snapjump_cli.geometry.designs import get_design

            return get_design(str(design), R_i=R)
        if chosen[0].startswith("--eta-i"):
            vals = dict(zip(_DESIGN_OPTS, (eta_i, theta_i, eta_o, theta_o)))
            missing = [k for k, v in vals.items() if v is None]
            if missing:
                raise BadInput(f"an explicit design needs {', '.join(_DESIGN_OPTS)}; missing {', '.join(missing)}")
            vals = {k: _finite(k, v) for k, v in vals.items()}
            mu = 1.0 if mu_ratio is None else _finite("--mu-ratio", mu_ratio)
            return Design(eta_i=vals["--eta-i"], theta_i_deg=vals["--theta-i"], eta_o=vals["--eta-o"],
                          theta_o_deg=vals["--theta-o"], mu_ratio=mu, R_i=R)
        kind = cap or "inner"
        missing = [k for k, v in (("--theta", theta), ("--eta", eta)) if v is None]
        if missing:
            raise BadInput(f"a single cap needs --theta and --eta; missing {', '.join(missing)}")
        if kind == "outer" and bc is not None:
            raise BadInput(f"--bc {bc} applies to inner caps only (an outer cap's base is always fixed)")
        return CapScene(theta_deg=_finite("--theta", theta), eta=_finite("--eta", eta), kind=kind,
                        bc=bc or "clamped", R=R)
    except InvalidDesign as e:
        raise BadInput("invalid scene: " + " ".join(str(e).split())) from None


def mesh_settings_from_options(order: int | str = _MS.order, nt: int = _MS.nt, aspect: float = _MS.aspect) -> MeshSettings:
    """:class:`MeshSettings` from the ``--order/--nt/--aspect`` values (BadInput when invalid; the
    ranges are those of :class:`MeshSettings`, the same as in a YAML config)."""
    if str(order) not in ("1", "2"):
        raise BadInput(f"--order must be 1 or 2, got {order!r}")
    aspect = _finite("--aspect", aspect)
    try:
        return MeshSettings(order=int(order), nt=nt, aspect=aspect)
    except SettingsError as e:
        raise BadInput(f"--{e.field}: expected {e.expected}, got {e.value!r}") from None
