"""The snap under air (snapjump_cli/fe/air_snap.py, docs/air.md): limits, eq 9, the energy two ways,
an independent check from the water path, stability under the gas and the off-path lower state."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import CubicSpline
from scipy.optimize import brentq

from snapjump_cli.geometry.designs import get_design
from snapjump_cli.fe.axisym.fluid import FluidSettings
from snapjump_cli.fe.axisym.lower_state import constrained_instability, snap_at_fixed_volume
from snapjump_cli.fe.axisym.descent import descend_at_volume
from snapjump_cli.settings import SolverSettings
from snapjump_cli.fe.solve import solve_checked, solve_scene

P0 = 101325.0


def _air(V0_ml: float, gamma: float = 1.0) -> FluidSettings:
    return FluidSettings(kind="air", V0_ml=V0_ml, gamma=gamma)


@pytest.fixture(scope="module")
def water_C():
    return solve_checked(get_design("C"))


@pytest.fixture(scope="module")
def air_C():
    return {v: solve_checked(get_design("C"), fluid=_air(v)) for v in (45.0, 1000.0)}


def test_water_answers_are_kept_beside_the_air_ones(water_C, air_C):
    """One trace serves both fluids: the water answers of an air run are the water run's, bit for bit."""
    w = water_C.metrics
    assert w["fluid"] == "water" and w["p_before_Pa"] is None and w["water_dE_J"] is None
    for res in air_C.values():
        m = res.metrics
        assert m["fluid"] == "air" and m["snaps"] and m["lower_state_method"] == "path"
        assert m["water_dE_J"] == w["dE_J"] and m["water_dy_pole_m"] == w["dy_pole_m"]
        assert m["water_h_imp_m"] == w["h_imp_m"] and m["p_max_Pa"] == w["p_max_Pa"]


def test_small_gas_volume_recovers_water(water_C):
    """V0_sys -> 0: the snap of volume control, within 0.5 % (here 1e-5)."""
    w = water_C.metrics
    m = solve_checked(get_design("C"), fluid=_air(1e-3)).metrics
    for air_key, water_key in (("dE_J", "dE_J"), ("dy_pole_m", "dy_pole_m"), ("h_imp_m", "h_imp_m"),
                               ("p_before_Pa", "p_star_Pa"), ("p_after_Pa", "p_lower_Pa")):
        assert m[air_key] == pytest.approx(w[water_key], rel=1e-5), air_key
    assert abs(m["dE_gas_J"]) < 1e-5 * m["dE_J"]


def test_large_gas_volume_snaps_at_the_pressure_maximum(water_C):
    """V0_sys -> infinity (pressure control): the snap comes at the pressure maximum and ends at the
    same pressure."""
    m = solve_checked(get_design("C"), fluid=_air(1e7)).metrics
    p_max = water_C.metrics["p_max_Pa"]
    assert m["p_before_Pa"] == pytest.approx(p_max, rel=1e-5)
    assert m["p_after_Pa"] == pytest.approx(p_max, rel=1e-3)


def test_snap_between_the_pressure_maximum_and_the_volume_limit(water_C, air_C):
    w = water_C.metrics
    p = [air_C[v].metrics["p_before_Pa"] for v in (45.0, 1000.0)]
    assert w["p_star_Pa"] < p[0] < p[1] < w["p_max_Pa"]


@pytest.mark.parametrize("V0", [45.0, 1000.0])
def test_volume_change_obeys_eq9(air_C, V0):
    """At constant dispensed volume the actuator grows by p0 V0 (p- - p+) / (p+ p-) (absolute
    pressures; eq 9, the sign of the issue's eq 10), to the solver's tolerance."""
    m = air_C[V0].metrics
    Pm, Pp = P0 + m["p_before_Pa"], P0 + m["p_after_Pa"]
    eq9 = P0 * V0 * 1e-6 * (Pm - Pp) / (Pp * Pm)
    assert m["dV_snap_m3"] > 0
    assert m["dV_snap_m3"] == pytest.approx(eq9, rel=1e-8)
    assert m["dV_snap_eq9_m3"] == pytest.approx(eq9, rel=1e-12)


@pytest.mark.parametrize("V0", [45.0, 1000.0])
def test_energy_two_ways(air_C, V0):
    """dE from the energies of rubber and gas in the two states, and -integral p dV_d along the path."""
    m = air_C[V0].metrics
    assert m["dE_J"] == pytest.approx(m["dE_rubber_J"] + m["dE_gas_J"], rel=1e-14)
    assert m["dE_rel_diff"] < 2e-5
    assert m["dE_path_J"] == pytest.approx(m["dE_J"], rel=2e-5)
    assert m["dE_gas_J"] > 0


@pytest.mark.parametrize("name,V0,full", [("C", 45.0, False), ("D", 45.0, False), ("C", 1000.0, True)])
def test_independent_check_from_the_water_path(name, V0, full):
    """By hand, from the traced water path's points only: the dispensed volume along them, its first
    maximum and its return (cubic splines in arc length) give the air snap's pressures and volume."""
    res = solve_checked(get_design(name), solver=SolverSettings(full=full))
    c = res.curve
    p, s = np.asarray(c["p_Pa"]), np.asarray(c["s"])
    V0_m3 = V0 * 1e-6
    Vd = (np.asarray(c["V_m3"]) - c["V0_m3"]) + V0_m3 - V0_m3 * P0 / (P0 + p)  # eq 7-8
    k = next(i for i in range(1, len(Vd) - 1) if Vd[i] >= Vd[i - 1] and Vd[i] > Vd[i + 1])
    sV, sp = CubicSpline(s, Vd), CubicSpline(s, p)
    s_up = brentq(sV.derivative(), s[k - 1], s[k + 1])
    Vd_star = float(sV(s_up))
    j = next(i for i in range(k + 1, len(Vd)) if Vd[i] >= Vd_star > Vd[i - 1])
    s_lo = brentq(lambda x: sV(x) - Vd_star, s[j - 1], s[j])
    m = solve_checked(get_design(name), fluid=_air(V0)).metrics
    assert m["V_disp_m3"] == pytest.approx(Vd_star, rel=1e-5)
    assert m["p_before_Pa"] == pytest.approx(float(sp(s_up)), rel=1e-4)
    assert m["p_after_Pa"] == pytest.approx(float(sp(s_lo)), rel=1e-3)


def test_stability_under_the_gas_is_that_of_the_series_spring():
    """Unstable modes under the gas (bordered inertia) = negative eigenvalues of K + g g^T / c, at
    states before, during and after the snap; between pressure and volume control, and changing at
    the limit of the dispensed volume: the last point before it is unstable under pressure control
    but stable under the gas, the first after it unstable under the gas but stable at fixed volume."""
    res = solve_scene(get_design("C"), fluid=_air(45.0))
    air, model = res.air, res.model
    pts = res.path.points
    st = air.states
    k = st.k_before
    counts = []
    for pt in (pts[k // 2], pts[k], pts[k + 1], pts[(k + st.k_return) // 2], st.lower):
        lin = model.linearize(pt.u, pt.p)
        K = lin.stiffness().toarray()
        c = float(air.gas.compliance(pt.p))
        lam = np.linalg.eigvalsh(K + np.outer(lin.g, lin.g) / c)
        n_gas = int(np.sum(lam < -1e-12 * np.abs(lam).max()))  # eigvalsh: ~1e-16 |M|
        assert air.unstable_modes(pt) == n_gas
        counts.append((n_gas, pt.n_neg, constrained_instability(air.tracer, lin)))  # gas, pressure, volume
    assert counts == [(0, 0, 0), (0, 1, 0), (1, 1, 0), (1, 1, 1), (0, 0, 0)]


def test_lower_state_off_the_path_under_the_gas(air_C):
    """The fixed-volume path under the gas constraint finds the path's post-snap state."""
    res = solve_scene(get_design("C"), fluid=_air(45.0))
    air, model = res.air, res.model
    st = air.states
    low, msg = snap_at_fixed_volume(air.tracer, st.upper, control=air.control)
    assert low is not None, msg

    def energy(pt):
        return model.energy(pt.u) + float(air.gas.energy(pt.p))

    assert np.abs(low.u - st.lower.u).max() < 1e-10
    assert energy(st.upper) - energy(low) == pytest.approx(energy(st.upper) - energy(st.lower), rel=1e-10)


def test_energy_descent_under_the_gas():
    """The fallback, the energy descent at fixed dispensed volume, lands on the path's post-snap
    state too (from the upper state along its unstable mode)."""
    res = solve_scene(get_design("C"), fluid=_air(45.0))
    air = res.air
    st = air.states
    low, msg = descend_at_volume(air.tracer, st.upper, control=air.control)
    assert low is not None, msg
    assert np.abs(low.u - st.lower.u).max() < 1e-9 and low.p == pytest.approx(st.lower.p, rel=1e-9)
    assert air.unstable_modes(low) == 0
