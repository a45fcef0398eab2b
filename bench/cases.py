"""The benchmark scenes: the Fig. 1 caps, the named designs A-D and random paper-grid designs."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from snapjump_cli.geometry.caps import CapScene, Design, InvalidDesign

REPO = Path(__file__).resolve().parents[1]
PAPER_GRID = REPO / "configs" / "paper_grid.yaml"


def json_value(v):
    """A result value as JSON takes it: numpy scalars as Python ones, NaN and infinities as ``None``
    (the benchmarks' row files)."""
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, float) and not np.isfinite(v):
        return None
    return v


@dataclass(frozen=True)
class Case:
    """One benchmark scene.

    Attributes
    ----------
    name : short identifier used in tables and on the command line
    scene : the :class:`CapScene` or :class:`Design`
    group : ``cap``, ``named`` or ``grid``
    label : human-readable description
    """

    name: str
    scene: CapScene | Design
    group: str
    label: str


def cap_cases() -> list[Case]:
    """The caps of Fig. 1 (:data:`snapjump_cli.geometry.designs.FIG1_CAPS`)."""
    from snapjump_cli.geometry.designs import fig1_caps

    return [Case(name, sc, "cap", f"cap theta=60, eta={sc.eta:g}, {sc.bc}") for name, sc in fig1_caps().items()]


def named_cases(names: tuple[str, ...] = ("A", "B", "C", "D")) -> list[Case]:
    """The paper's named designs (``snapjump_cli/geometry/designs.yaml``)."""
    from snapjump_cli.geometry.designs import get_design

    out = []
    for n in names:
        d = get_design(n)
        out.append(Case(f"design-{n}", d, "named",
                        f"design {n} (eta_i={d.eta_i:g}, theta_i={d.theta_i_deg:g}, eta_o={d.eta_o:g}, "
                        f"theta_o={d.theta_o_deg:g}, mu_i/mu_o={d.mu_ratio:g})"))
    return out


def grid_cases(n: int = 10, seed: int = 20240605, config: Path = PAPER_GRID) -> list[Case]:
    """``n`` valid designs drawn uniformly (without replacement, fixed ``seed``) from the points of
    the paper grid (``configs/paper_grid.yaml``, docs/physics.md section 8); invalid ones are skipped."""
    from snapjump_cli.sweep.config import load_config

    cfg = load_config(config)
    points = list(cfg.designs())
    rng = np.random.default_rng(seed)
    out = []
    for i in rng.permutation(len(points)):
        p = points[int(i)]
        try:
            d = Design(**p.design_kwargs())
        except InvalidDesign:
            continue
        out.append(Case(f"grid-{p.index:04d}", d, "grid",
                        f"grid #{p.index} (eta_i={p.eta_i:.3g}, theta_i={p.theta_i_deg:.3g}, eta_o={p.eta_o:.3g}, "
                        f"theta_o={p.theta_o_deg:.3g}, mu_i/mu_o={p.mu_ratio:g})"))
        if len(out) >= n:
            break
    return out


def all_cases(n_grid: int = 10, seed: int = 20240605) -> list[Case]:
    return cap_cases() + named_cases() + grid_cases(n_grid, seed)


def select(cases: list[Case], patterns: list[str] | None) -> list[Case]:
    """Cases whose name matches any of the shell-style ``patterns`` (all when None), or a group name."""
    if not patterns:
        return cases
    import fnmatch

    out = [c for c in cases if any(fnmatch.fnmatchcase(c.name, p) or c.group == p for p in patterns)]
    if not out:
        raise SystemExit(f"--scenes {' '.join(patterns)}: no scene matches; known: {', '.join(c.name for c in cases)}")
    return out
