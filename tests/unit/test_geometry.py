"""Geometry (paper S1, eqs 1-6) and the named designs."""
from __future__ import annotations

import math

import pytest

from snapjump_cli.geometry.designs import get_design, named_designs, paper_values
from snapjump_cli.geometry.caps import CapScene, Design, InvalidDesign, design_points, design_volumes

NAMES = ("A", "B", "C", "D", "S20b", "S20c")


def _eq3(eta_i, theta_i_deg, eta_o, theta_o_deg, R_i):
    """Eq 3a/3b written out independently of geometry.py."""
    ci, co = math.cos(math.radians(theta_i_deg)), math.cos(math.radians(theta_o_deg))
    ratio = math.sqrt(((1 + 1 / (2 * eta_i)) ** 2 - ci**2) / ((1 - 1 / (2 * eta_o)) ** 2 - co**2))
    return R_i * ratio, R_i * (ci - co * ratio)


def test_named_designs_table():
    d = named_designs()
    assert set(NAMES) <= set(d)
    # docs/physics.md section 7
    assert (d["C"]["eta_i"], d["C"]["theta_i"], d["C"]["eta_o"], d["C"]["theta_o"], d["C"]["mu_ratio"]) == (
        8.5, 60, 16.5, 90, 5.8)
    assert (d["D"]["eta_i"], d["D"]["theta_i"], d["D"]["eta_o"], d["D"]["theta_o"]) == (6.2, 80, 12.1, 82)
    d["C"]["eta_i"] = -1.0  # a copy: the cache is untouched
    assert named_designs()["C"]["eta_i"] == 8.5


@pytest.mark.parametrize("name", NAMES)
def test_eq3_and_eq2_closure(name):
    entry = named_designs()[name]
    d = get_design(name)
    assert d.name == name and d.R_i == 0.030
    assert (d.eta_i, d.theta_i_deg, d.eta_o, d.theta_o_deg, d.mu_ratio) == (
        entry["eta_i"], entry["theta_i"], entry["eta_o"], entry["theta_o"], entry["mu_ratio"])
    R_o, Delta = _eq3(d.eta_i, d.theta_i_deg, d.eta_o, d.theta_o_deg, d.R_i)
    assert d.R_o == pytest.approx(R_o, rel=1e-13)
    assert d.Delta == pytest.approx(Delta, rel=1e-13, abs=1e-15)
    p = design_points(d)
    x6i, y6i = p["6i"]
    x6o, y6o = p["6o"]
    assert abs(x6i - x6o) <= 1e-12 * abs(x6i)
    assert abs(y6i - y6o) <= 1e-12 * max(abs(y6i), d.R_i)
    # eq 5 holds and the points are where eqs 1 and 6 put them
    assert p["2"][1] < p["3"][1]
    assert p["1"] == (0.0, pytest.approx(d.R_i * (1 - 0.5 / d.eta_i)))
    assert p["9"][0] == pytest.approx(x6i + d.R_i / 10)
    assert p["8"][1] == pytest.approx(p["7"][1] - d.R_i / 30)
    v = design_volumes(d)
    assert all(v[k] > 0 for k in ("inner_cap", "ring", "outer_solid", "cavity"))


def test_design_C_numbers():
    d = get_design("C")
    assert d.Delta == pytest.approx(0.015, rel=1e-12)  # cos 90 = 0: Delta = R_i cos 60
    assert d.R_o == pytest.approx(0.0288749, rel=1e-5)


def test_get_design_overrides_and_case():
    d = get_design("c", R_i=0.02, theta_i=55)
    assert d.name == "C" and d.R_i == 0.02 and d.theta_i_deg == 55
    with pytest.raises(InvalidDesign, match="unknown design parameter 'colour'"):
        get_design("C", colour=1)


def test_unknown_design_lists_known():
    with pytest.raises(InvalidDesign) as e:
        get_design("Zebra")
    msg = str(e.value)
    assert "'Zebra'" in msg and all(n in msg for n in NAMES)


def test_paper_values():
    pv = paper_values("C")
    assert pv["paper_dE_J"] == pytest.approx(31.4e-3)
    assert pv["paper_dy_pole_m"] == pytest.approx(20.89e-3)
    assert all(k.startswith("paper_") for k in pv)
    assert "paper_dE_J" not in paper_values("S20b")
    with pytest.raises(InvalidDesign):
        paper_values("nope")


GOOD = dict(eta_i=8.5, theta_i_deg=60.0, eta_o=16.5, theta_o_deg=90.0, mu_ratio=5.8)


@pytest.mark.parametrize(
    "changes, pattern",
    [
        (dict(theta_i_deg=90.0, theta_o_deg=60.0), r"theta_i < theta_o.*90.*60"),
        (dict(theta_i_deg=70.0, theta_o_deg=70.0), r"theta_i < theta_o"),
        (dict(eta_i=5.0, theta_i_deg=70.0, eta_o=5.0, theta_o_deg=72.0), r"y_2 < y_3.*y_2 = 0\.033"),
        (dict(eta_i=0.5), r"eta_i.*> 0\.5.*0\.5"),
        (dict(eta_o=0.3), r"eta_o.*> 0\.5.*0\.3"),
        (dict(eta_i=float("nan")), r"eta_i must be finite, got nan"),
        (dict(theta_o_deg=float("nan")), r"theta_o.*nan"),
        (dict(eta_i=-3.0), r"eta_i must be > 0, got -3"),
        (dict(R_i=-0.03), r"R_i must be > 0, got -0\.03"),
        (dict(t_ring_frac=-0.1), r"t_ring_frac must be > 0"),
        (dict(mu_ratio=0.0), r"mu_ratio must be > 0, got 0"),
        (dict(theta_o_deg=200.0), r"theta_o must lie in \(0, 180\).*200"),
        (dict(theta_i_deg=0.0), r"theta_i must lie in \(0, 180\).*0"),
        (dict(theta_i_deg=-10.0), r"theta_i must lie in \(0, 180\).*-10"),
    ],
)
def test_invalid_designs(changes, pattern):
    with pytest.raises(InvalidDesign, match=pattern):
        Design(**{**GOOD, **changes})


@pytest.mark.parametrize(
    "kwargs, pattern",
    [
        (dict(theta_deg=60.0, eta=0.4), r"eta.*> 0\.5"),
        (dict(theta_deg=float("nan"), eta=8.5), r"theta.*nan"),
        (dict(theta_deg=180.0, eta=8.5), r"\(0, 180\).*180"),
        (dict(theta_deg=60.0, eta=8.5, bc="glued"), r"bc must be one of.*'glued'"),
        (dict(theta_deg=60.0, eta=8.5, R=-1.0), r"R must be > 0"),
        (dict(theta_deg=170.0, eta=10.0), r"does not reach the base plane"),
    ],
)
def test_invalid_caps(kwargs, pattern):
    with pytest.raises(InvalidDesign, match=pattern):
        CapScene(**kwargs)
