"""The named designs of the paper (S2 and S20; docs/physics.md section 7), read from the package
data file ``snapjump_cli/geometry/designs.yaml`` (with :mod:`importlib.resources`, so an installed
wheel finds it as well as a checkout).

Each YAML entry holds the design parameters ``eta_i, theta_i, eta_o, theta_o, mu_ratio``
(angles in degrees) and the paper's reported values ``paper_*`` (SI units).
"""
from __future__ import annotations

import copy
import dataclasses
from functools import lru_cache
from importlib import resources

from snapjump_cli.geometry.caps import CapScene, Design, InvalidDesign

__all__ = ["DESIGNS_YAML", "FIG1_CAPS", "fig1_caps", "named_designs", "get_design", "paper_values", "resolve_name"]

#: Where the named designs are read from (a Traversable of the installed package).
DESIGNS_YAML = resources.files("snapjump_cli.geometry") / "designs.yaml"

# YAML key -> Design field
_PARAM_KEYS = {
    "eta_i": "eta_i",
    "theta_i": "theta_i_deg",
    "eta_o": "eta_o",
    "theta_o": "theta_o_deg",
    "mu_ratio": "mu_ratio",
}
_DESIGN_FIELDS = {f.name for f in dataclasses.fields(Design)}


@lru_cache(maxsize=1)
def _load() -> dict[str, dict]:
    import yaml

    data = yaml.safe_load(DESIGNS_YAML.read_text(encoding="utf-8")) or {}
    if not isinstance(data, dict):
        raise ValueError(f"{DESIGNS_YAML}: expected a mapping of design names, got {type(data).__name__}")
    out: dict[str, dict] = {}
    for name, entry in data.items():
        if not isinstance(entry, dict):
            raise ValueError(f"{DESIGNS_YAML}: design {name!r} is not a mapping")
        missing = [k for k in _PARAM_KEYS if k not in entry]
        if missing:
            raise ValueError(f"{DESIGNS_YAML}: design {name!r} lacks {', '.join(missing)}")
        out[str(name)] = dict(entry)
    return out


def named_designs() -> dict[str, dict]:
    """All named designs as ``{name: {eta_i, theta_i, eta_o, theta_o, mu_ratio, paper_*...}}``
    (a fresh copy: mutating it does not change the cache)."""
    return copy.deepcopy(_load())


def resolve_name(name: str) -> str:
    """The canonical spelling of a design name (exact match first, then case-insensitive).

    Raises :class:`InvalidDesign` naming ``name`` and listing the known designs.
    """
    designs = _load()
    if name in designs:
        return name
    folded = [k for k in designs if k.casefold() == str(name).casefold()]
    if len(folded) == 1:
        return folded[0]
    raise InvalidDesign(f"unknown design {name!r}; known designs: {', '.join(designs)}")


def get_design(name: str, **overrides) -> Design:
    """The named design as a :class:`Design`.

    ``overrides`` replace any :class:`Design` field (``R_i``, ``mu_i``, ``J_m``, ``t_ring_frac``,
    ...); the YAML spellings ``theta_i`` / ``theta_o`` (degrees) are accepted too.
    Unknown names or override keys raise :class:`InvalidDesign`.
    """
    key = resolve_name(name)
    entry = _load()[key]
    params = {field: float(entry[k]) for k, field in _PARAM_KEYS.items()}
    for k, v in overrides.items():
        field = _PARAM_KEYS.get(k, k)
        if field not in _DESIGN_FIELDS or field == "name":
            raise InvalidDesign(f"unknown design parameter {k!r}; known: {', '.join(sorted(_DESIGN_FIELDS - {'name'}))}")
        params[field] = v
    return Design(**params, name=key)


def paper_values(name: str) -> dict:
    """The paper's reported values of a named design: its ``paper_*`` entries (SI units)."""
    entry = _load()[resolve_name(name)]
    return {k: v for k, v in entry.items() if k.startswith("paper_")}


#: The single caps of the paper's Fig. 1 (theta = 60 deg; eta = 30 clamped, eta = 8.5 under the four
#: base conditions of docs/physics.md section 1): name -> (eta, bc, the paper's (dE / (mu R^3), dy / R)).
FIG1_CAPS: dict[str, tuple[float, str, tuple[float, float]]] = {
    "cap30-clamped": (30.0, "clamped", (1.50e-5, 0.131)),
    "cap8.5-clamped": (8.5, "clamped", (4.78e-6, 0.063)),
    "cap8.5-roller": (8.5, "roller", (8.00e-4, 0.267)),
    "cap8.5-roller-point": (8.5, "roller-point", (8.00e-4, 0.267)),
    "cap8.5-ring-roller": (8.5, "ring-roller", (8.00e-4, 0.267)),
}


def fig1_caps(names: tuple[str, ...] | None = None) -> dict[str, CapScene]:
    """The Fig. 1 caps as :class:`~snapjump_cli.geometry.caps.CapScene` objects (all, or ``names``), in
    the order of :data:`FIG1_CAPS`; their paper values are ``FIG1_CAPS[name][2]``."""
    keys = list(FIG1_CAPS) if names is None else list(names)
    return {k: CapScene(theta_deg=60.0, eta=FIG1_CAPS[k][0], bc=FIG1_CAPS[k][1]) for k in keys}
