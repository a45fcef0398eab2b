"""Tests of the two-mass jump model (snapjump_cli.jump; docs/physics.md section 6)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm

from snapjump_cli.jump import (
    JumpParams,
    JumpResult,
    eigensystem,
    jump_height,
    jump_height_ode,
    jump_trajectory,
    masses,
    spring_stiffness,
    system_matrices,
)

RHO = 1000.0
# paper-like inputs (docs/physics.md section 7; volumes in m^3 times rho)
C = dict(dE_J=31.4e-3, dy_pole_m=20.89e-3, m_i_kg=RHO * 1.1224e-5, m_o_kg=RHO * 9.170e-6)
D = dict(dE_J=0.324, dy_pole_m=31.7e-3, m_i_kg=RHO * 2.42e-5, m_o_kg=RHO * 1.72e-5)
# weak designs with design-C masses
A_LIKE = dict(dE_J=0.875e-3, dy_pole_m=7.68e-3, m_i_kg=C["m_i_kg"], m_o_kg=C["m_o_kg"])
B_LIKE = dict(dE_J=5.67e-3, dy_pole_m=7.55e-3, m_i_kg=C["m_i_kg"], m_o_kg=C["m_o_kg"])
# over-damped (c_d^2 M > 4 k m_i m_o) and jumping
OVER = dict(dE_J=1e-3, dy_pole_m=5e-3, m_i_kg=2e-4, m_o_kg=1e-4)


def _critical(m_i: float = 2e-4, m_o: float = 1e-4, dy: float = 5e-3, c_d: float = 0.4) -> dict:
    k = c_d**2 * (m_i + m_o) / (4.0 * m_i * m_o)
    return dict(dE_J=0.5 * k * dy**2, dy_pole_m=dy, m_i_kg=m_i, m_o_kg=m_o)


def _energy(traj, t: np.ndarray, p: JumpParams) -> np.ndarray:
    """Kinetic + gravitational + spring energy along a trajectory (up to a constant)."""
    yi, yo, vi, vo = traj.state(t)
    r = traj.result
    e = yo - yi - traj.L_rest
    return (0.5 * r.m_i * vi**2 + 0.5 * r.m_o * vo**2 + p.g * (r.m_i * yi + r.m_o * yo)
            + 0.5 * r.k_s * e**2)


def _dense_times(traj, n: int = 20001) -> np.ndarray:
    t = np.linspace(0.0, traj.t_end, n)
    extra = [tc + s for tc in traj.contact_times for s in (-1e-9, -1e-12, 0.0, 1e-12, 1e-9)]
    return np.unique(np.clip(np.concatenate([t, extra]), 0.0, traj.t_end))


# ----------------------------------------------------------------------------- closed form vs ODE
CASES = [
    ("C h=0", C, 0.0, JumpParams()),
    ("C h=2mm", C, 2e-3, JumpParams()),
    ("C h=5mm", C, 5e-3, JumpParams()),
    ("C h=10mm", C, 10e-3, JumpParams()),
    ("D h=0", D, 0.0, JumpParams()),
    ("D h=10mm", D, 10e-3, JumpParams()),
    ("D h=15mm", D, 15e-3, JumpParams()),
    ("D h=20mm", D, 20e-3, JumpParams()),
    ("B-like h=0", B_LIKE, 0.0, JumpParams()),
    ("B-like h=1mm", B_LIKE, 1e-3, JumpParams()),
    ("overdamped h=0", OVER, 0.0, JumpParams()),
    ("overdamped h=0.2mm", OVER, 0.2e-3, JumpParams()),
    ("critical h=0", _critical(), 0.0, JumpParams()),
    ("C plastic h=3mm", C, 3e-3, JumpParams(alpha=0.0)),
    ("C elastic h=3mm", C, 3e-3, JumpParams(alpha=1.0)),
    ("D undamped h=5mm", D, 5e-3, JumpParams(c_d=0.0)),
    ("D heavy damping h=5mm", D, 5e-3, JumpParams(c_d=2.0)),
]


@pytest.mark.parametrize("name,design,h,p", CASES, ids=[c[0] for c in CASES])
def test_closed_form_matches_ode(name, design, h, p):
    r = jump_height(h_imp_m=h, params=p, **design)
    ro = jump_height_ode(h_imp_m=h, params=p, **design)
    assert r.complete and ro.complete
    assert r.jumped and ro.jumped, (r, ro)
    assert r.y_jump_m > h
    assert abs(r.y_jump_m - ro.y_jump_m) <= 1e-9 * r.y_jump_m, (r.y_jump_m, ro.y_jump_m)
    assert abs(r.t_peak_s - ro.t_peak_s) <= 1e-8 * r.t_peak_s
    assert r.n_contacts == ro.n_contacts
    assert r.lift_off and ro.lift_off and r.reason == ro.reason == ""
    assert r.method == "closed-form" and ro.method == "ode"


def test_weak_design_never_leaves_ground():
    for fn in (jump_height, jump_height_ode):
        r = fn(h_imp_m=0.0, **A_LIKE)
        assert r.y_jump_m == 0.0 and r.t_peak_s == 0.0
        assert not r.jumped and not r.lift_off
        assert r.reason == "never leaves the ground"
        assert r.complete and r.n_contacts == 0
        # started above the ground it falls, bounces, and never regains its start height
        r = fn(h_imp_m=3e-3, **A_LIKE)
        assert r.y_jump_m == 3e-3 and r.t_peak_s == 0.0 and r.rise_m == 0.0
        assert not r.jumped and r.lift_off and r.n_contacts >= 1
        assert r.reason == "never rises above its start height h_imp"


def test_weak_design_stays_on_ground_in_trajectory():
    traj = jump_trajectory(h_imp_m=0.0, **A_LIKE)
    t = np.linspace(0.0, traj.t_end, 2001)
    yi, _, vi, _ = traj.state(t)
    assert np.all(yi == 0.0) and np.all(vi == 0.0)
    assert traj.phases[0][0] == "rest"


@pytest.mark.parametrize("fn", [jump_height, jump_height_ode])
@pytest.mark.parametrize("dE,dy,fragment", [(0.0, 0.02, "no snap (dE = 0)"),
                                             (-1e-3, 0.02, "no snap"),
                                             (0.03, 0.0, "no pole travel"),
                                             (0.03, -0.01, "no pole travel")])
def test_non_snapper(fn, dE, dy, fragment):
    r = fn(dE, dy, 4e-3, C["m_i_kg"], C["m_o_kg"])
    assert isinstance(r, JumpResult)
    assert not r.jumped and not r.lift_off
    assert r.y_jump_m == 4e-3 and r.t_peak_s == 0.0 and r.k_s == 0.0 and r.n_contacts == 0
    assert fragment in r.reason


# ----------------------------------------------------------------------------- closed form itself
@pytest.mark.parametrize("design,c_d", [(C, 0.4), (D, 0.4), (OVER, 0.4), (_critical(), 0.4),
                                        (D, 0.0)])
def test_eigensystem_corrected(design, c_d):
    k = spring_stiffness(design["dE_J"], design["dy_pole_m"])
    mi, mo = design["m_i_kg"], design["m_o_kg"]
    A, _ = system_matrices(k, mi, mo, c_d, 9.81, 0.03)
    lam, P = eigensystem(k, mi, mo, c_d)
    assert np.allclose(A @ P[:, 0], 0.0)
    assert np.allclose(A @ P[:, 1], P[:, 0])  # generalised eigenvector of the double 0
    for j in (2, 3):
        assert np.allclose(A @ P[:, j], lam[j] * P[:, j], rtol=1e-12, atol=1e-12 * abs(lam[j]))
    # lambda_3 != lambda_4 (the paper prints them identically) unless critically damped
    ev = np.linalg.eigvals(A)
    tol = 1e-5 * np.max(np.abs(ev))
    for lj in lam:  # each corrected eigenvalue is one of numpy's (the double 0 is defective)
        assert np.min(np.abs(ev - lj)) <= tol
    if abs(c_d**2 * (mi + mo) - 4 * k * mi * mo) > 1e-9 * 4 * k * mi * mo:
        assert abs(lam[2] - lam[3]) > tol


def test_paper_printed_eigenvector_is_wrong():
    k = spring_stiffness(C["dE_J"], C["dy_pole_m"])
    mi, mo = C["m_i_kg"], C["m_o_kg"]
    A, _ = system_matrices(k, mi, mo, 0.4, 9.81, 0.03)
    lam, P = eigensystem(k, mi, mo, 0.4)
    printed = P[:, 2].copy()
    printed[1] = -printed[1]  # the paper's +2 m_i m_o / X
    assert not np.allclose(A @ printed, lam[2] * printed)
    assert abs(lam[2] - lam[3]) > 1.0


def _expm_extended(M: np.ndarray) -> np.ndarray:
    """``exp(M)`` in x87 extended precision (``np.longdouble``): a 30-term Taylor series after
    scaling to norm <= 1/2, then squaring; no BLAS, so the same digits on every x86-64 CPU.
    (scipy's ``expm`` in double precision was off by 1.1e-11 relative on a critically damped
    flight, more than this test's tolerance; the closed form agrees with this one to 5e-13.)"""
    M = np.asarray(M, np.longdouble)
    nrm = float(np.abs(M).sum(axis=0).max())
    s = max(0, int(np.ceil(np.log2(nrm))) + 1) if nrm > 0 else 0
    A = M / np.longdouble(2) ** s
    E = np.eye(M.shape[0], dtype=np.longdouble)
    T = E.copy()
    for k in range(1, 30):
        T = T @ A / k
        E = E + T
    for _ in range(s):
        E = E @ E
    return E


def test_the_extended_precision_exponential_is_exact_on_a_rotation():
    th = 40.0
    E = _expm_extended(np.array([[0.0, -th], [th, 0.0]]))
    np.testing.assert_allclose(np.asarray(E, float), [[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]],
                               rtol=0, atol=2e-15)
    np.testing.assert_allclose(np.asarray(_expm_extended(np.diag([1.0, -3.0])), float), np.diag(np.exp([1.0, -3.0])),
                               rtol=1e-15)
    assert np.allclose(np.asarray(_expm_extended(np.diag([1.0, -3.0])), float), expm(np.diag([1.0, -3.0])))


def _expm_propagate(design, p: JumpParams, L_rest: float, Y0: np.ndarray, t: np.ndarray):
    k = spring_stiffness(design["dE_J"], design["dy_pole_m"])
    A, B = system_matrices(k, design["m_i_kg"], design["m_o_kg"], p.c_d, p.g, L_rest)
    Aug = np.zeros((5, 5))
    Aug[:4, :4] = A
    Aug[:4, 4] = B
    Z0 = np.append(Y0, 1.0).astype(np.longdouble)
    return np.array([np.asarray(_expm_extended(Aug * s) @ Z0, float)[:4] for s in t]).T


@pytest.mark.parametrize("design,p", [(C, JumpParams()), (D, JumpParams()),
                                      (OVER, JumpParams()), (_critical(), JumpParams()),
                                      (D, JumpParams(c_d=0.0, g=0.0))])
def test_long_flight_matches_matrix_exponential(design, p):
    """Eqs 16-17 propagated by expm vs the modal closed form over a long first flight."""
    h = 0.3 if p.g > 0 else 0.05
    traj = jump_trajectory(h_imp_m=h, params=replace_tmax(p, 0.5), L0_m=0.02, **design)
    L_rest = traj.L_rest
    assert L_rest == pytest.approx(0.02 + design["dy_pole_m"])
    t_end = traj.contact_times[0] if traj.contact_times else traj.t_end
    t = np.linspace(0.0, t_end, 41)[1:]
    Y0 = np.array([h, h + 0.02, 0.0, 0.0])
    ref = _expm_propagate(design, p, L_rest, Y0, t)
    got = traj.state(t)
    vel_scale = np.max(np.abs(ref[2:]))
    pos_scale = max(h, np.max(np.abs(ref[:2])))
    assert np.all(np.abs(got[:2, :-1] - ref[:2, :-1]) <= 1e-11 * pos_scale)
    assert np.all(np.abs(got[2:, :-1] - ref[2:, :-1]) <= 1e-10 * vel_scale)
    if traj.contact_times:  # the first contact is exact: y_i(t_c) = 0 by expm too
        assert abs(ref[0, -1]) <= 1e-11 * pos_scale
        assert ref[2, -1] < 0.0


@pytest.mark.parametrize("design,h,p", [(C, 2e-3, JumpParams()), (C, 5e-3, JumpParams()),
                                        (D, 5e-3, JumpParams()), (D, 20e-3, JumpParams()),
                                        (OVER, 0.2e-3, JumpParams()),
                                        (C, 5e-3, JumpParams(c_d=0.0, g=0.0, alpha=0.8,
                                                             t_max=0.1))])
def test_every_phase_matches_matrix_exponential(design, h, p):
    """Chain the whole trajectory: each flight phase is expm-propagated from its start state,
    lands exactly on y_i = 0, and the next phase starts from the impact law
    (v_i <- -alpha v_i or rest, y_o and v_o unchanged)."""
    traj = jump_trajectory(h_imp_m=h, params=p, **design)
    L_rest = traj.L_rest
    n_flights = 0
    phases = traj.phases
    for j, (kind, a, b) in enumerate(phases):
        if kind != "flight" or b <= a:
            continue
        n_flights += 1
        Ya = traj.state(a)
        t = np.linspace(a, b, 25)[1:]
        ref = _expm_propagate(design, p, L_rest, Ya, t - a)
        got = traj.state(t[:-1])
        pos_scale = max(1e-3, np.max(np.abs(ref[:2])))
        vel_scale = max(1e-3, np.max(np.abs(ref[2:])))
        assert np.all(np.abs(got[:2] - ref[:2, :-1]) <= 1e-11 * pos_scale)
        assert np.all(np.abs(got[2:] - ref[2:, :-1]) <= 1e-10 * vel_scale)
        end = ref[:, -1]
        if b in traj.contact_times:
            assert abs(end[0]) <= 1e-12 * pos_scale and end[2] < 0.0
            nxt = traj.state(b)
            assert nxt[0] == 0.0
            assert nxt[1] == pytest.approx(end[1], abs=1e-12 * pos_scale)
            assert nxt[3] == pytest.approx(end[3], abs=1e-10 * vel_scale)
            if j + 1 < len(phases) and phases[j + 1][0] == "rest":
                assert nxt[2] == 0.0
            else:
                assert nxt[2] == pytest.approx(-p.alpha * end[2], rel=1e-9)
    assert n_flights >= 2


def replace_tmax(p: JumpParams, t_max: float) -> JumpParams:
    from dataclasses import replace
    return replace(p, t_max=t_max)


def test_centre_of_mass_and_energy_without_damping_and_gravity():
    """c_d = 0, g = 0, alpha = 1: energy conserved through impacts; the centre of mass moves
    uniformly between impacts and each impact adds exactly 2 m_i |v_i| of momentum."""
    p = JumpParams(c_d=0.0, g=0.0, alpha=1.0, t_max=0.2)
    traj = jump_trajectory(h_imp_m=5e-3, params=p, **C)
    r = traj.result
    assert not r.complete  # no gravity: it flies forever, t_max stops it
    t = _dense_times(traj, 4001)
    E = _energy(traj, t, p)
    assert np.max(np.abs(E - C["dE_J"])) <= 1e-9 * C["dE_J"]
    assert len(traj.contact_times) >= 1
    M = r.m_i + r.m_o
    edges = [0.0, *traj.contact_times, traj.t_end]
    P_before = 0.0
    for a, b in zip(edges[:-1], edges[1:]):
        if b - a < 1e-9:
            continue
        tt = np.linspace(a, b, 50)[1:-1]
        yi, yo, vi, vo = traj.state(tt)
        P = r.m_i * vi + r.m_o * vo
        assert np.ptp(P) <= 1e-12 * max(1.0, abs(P[0]))
        Yc = (r.m_i * yi + r.m_o * yo) / M
        assert np.allclose(np.diff(Yc, 2), 0.0, atol=1e-13)
        if a > 0.0:
            _, _, vi_minus, _ = traj.state(a - 1e-13)
            assert P[0] - P_before == pytest.approx(2.0 * r.m_i * abs(vi_minus), rel=1e-6)
        P_before = P[-1]


@pytest.mark.parametrize("design,h,p", [(C, 5e-3, JumpParams()), (D, 10e-3, JumpParams()),
                                        (OVER, 0.0, JumpParams()),
                                        (C, 3e-3, JumpParams(c_d=0.0, alpha=1.0, t_max=0.4))])
def test_energy_never_increases(design, h, p):
    traj = jump_trajectory(h_imp_m=h, params=p, **design)
    t = _dense_times(traj)
    E = _energy(traj, t, p)
    scale = design["dE_J"] + (design["m_i_kg"] + design["m_o_kg"]) * p.g * traj.result.y_jump_m
    assert np.all(np.diff(E) <= 1e-11 * scale)
    if p.c_d == 0.0 and p.alpha == 1.0:
        assert np.ptp(E) <= 1e-10 * scale


# ----------------------------------------------------------------------------- contacts and apex
@pytest.mark.parametrize("design,h", [(C, 0.0), (C, 2e-3), (C, 5e-3), (C, 20e-3), (D, 0.0),
                                      (D, 10e-3), (D, 20e-3), (B_LIKE, 1e-3), (OVER, 0.2e-3)])
def test_no_penetration_and_exact_apex(design, h):
    traj = jump_trajectory(h_imp_m=h, **design)
    r = traj.result
    t = _dense_times(traj)
    yi, yo, vi, vo = traj.state(t)
    assert np.min(yi) >= -1e-12
    assert np.max(yi) <= r.y_jump_m * (1 + 1e-12)
    # y_o is continuous everywhere, v_o across impacts too
    for tc in traj.contact_times:
        a, b = traj.state(tc - 1e-12), traj.state(tc + 1e-12)
        assert abs(a[1] - b[1]) <= 1e-9 and abs(a[3] - b[3]) <= 1e-6
        assert a[2] <= 0.0 and a[0] >= 0.0
        assert abs(a[0]) <= 1e-10
    if r.jumped:
        s = traj.state(r.t_peak_s)
        vscale = math.sqrt(2 * design["dE_J"] / design["m_i_kg"])
        assert abs(s[2]) <= 1e-10 * vscale
        assert s[0] == pytest.approx(r.y_jump_m, rel=1e-13)
        # it is a maximum of the dense trajectory
        near = np.linspace(r.t_peak_s - 1e-3, r.t_peak_s + 1e-3, 2001)
        assert np.max(traj.state(near)[0]) <= r.y_jump_m * (1 + 1e-13)
        assert (r.t_peak_s, r.y_jump_m) in traj.apexes
    else:
        assert r.y_jump_m == h and r.t_peak_s == 0.0


def test_contact_located_exactly():
    """Just before each impact y_i is |v_i| dt above the ground (first order), at it exactly 0."""
    traj = jump_trajectory(h_imp_m=5e-3, **D)
    assert len(traj.contact_times) >= 2
    for tc in traj.contact_times:
        for dt in (1e-6, 1e-8):
            y, _, v, _ = traj.state(tc - dt)
            if v < -1e-3:
                assert y == pytest.approx(-v * dt, rel=1e-2)
        assert traj.state(tc)[0] == 0.0  # the post-impact state


def test_resting_start_lifts_off_when_force_turns_upward():
    """h_imp = 0: m_i rests until k e + c e_dot - m_i g = 0, then leaves; the limit h_imp -> 0+
    gives the same jump."""
    traj = jump_trajectory(h_imp_m=0.0, **C)
    kind, t0, t1 = traj.phases[0]
    assert kind == "rest" and t0 == 0.0 and t1 > 0.0
    yi, yo, vi, vo = traj.state(np.linspace(0.0, t1, 101))
    assert np.all(yi == 0.0) and np.all(vi == 0.0)
    r = traj.result
    _, yo1, _, vo1 = traj.state(t1)
    e = yo1 - traj.L_rest
    assert r.k_s * e + 0.4 * vo1 - r.m_i * 9.81 == pytest.approx(0.0, abs=1e-10 * r.k_s * 0.02)
    assert traj.phases[1][0] == "flight" and r.lift_off
    assert traj.state(t1 + 1e-4)[0] > 0.0
    y0 = r.y_jump_m
    for h in (1e-12, 1e-9):
        assert jump_height(h_imp_m=h, **C).y_jump_m == pytest.approx(y0, abs=100 * h + 1e-12)


# ----------------------------------------------------------------------------- monotonicity etc.
@pytest.mark.parametrize("h", [0.0, 5e-3])
def test_more_energy_jumps_higher(h):
    dEs = np.linspace(0.05, 0.6, 12)
    ys = [jump_height(dE, D["dy_pole_m"], h, D["m_i_kg"], D["m_o_kg"]).y_jump_m for dE in dEs]
    assert np.all(np.diff(ys) > 0.0)


def test_result_fields_and_stiffness():
    r = jump_height(h_imp_m=5e-3, **C)
    assert r.k_s == pytest.approx(2 * C["dE_J"] / C["dy_pole_m"] ** 2, rel=1e-15)
    assert spring_stiffness(C["dE_J"], C["dy_pole_m"]) == r.k_s
    assert (r.m_i, r.m_o) == (C["m_i_kg"], C["m_o_kg"])
    assert r.h_imp_m == 5e-3 and r.rise_m == pytest.approx(r.y_jump_m - 5e-3)
    assert r.jumped and r.reason == "" and r.complete
    assert 0.0 < r.t_peak_s < 1.0 and r.n_contacts >= 1


def test_stops_are_flagged():
    r = jump_height(h_imp_m=5e-3, params=JumpParams(t_max=1e-3), **D)
    assert not r.complete
    r = jump_height(h_imp_m=5e-3, params=JumpParams(max_contacts=1), **D)
    assert not r.complete and r.n_contacts == 1


# ----------------------------------------------------------------------------- inputs
def test_masses():
    assert masses(1.1224e-5, 9.170e-6, 1000.0) == pytest.approx((1.1224e-2, 9.170e-3))
    assert masses(1e-5, 2e-5) == pytest.approx((1e-2, 2e-2))
    with pytest.raises(ValueError, match="V_inner_solid_m3"):
        masses(-1e-5, 1e-5)
    with pytest.raises(ValueError, match="V_outer_solid_m3"):
        masses(1e-5, float("nan"))
    with pytest.raises(ValueError, match="rho"):
        masses(1e-5, 1e-5, 0.0)


@pytest.mark.parametrize("fn", [jump_height, jump_height_ode])
@pytest.mark.parametrize("kw,name", [(dict(dE_J=float("nan")), "dE_J"),
                                     (dict(dy_pole_m=float("inf")), "dy_pole_m"),
                                     (dict(h_imp_m=-1e-3), "h_imp_m"),
                                     (dict(h_imp_m=float("nan")), "h_imp_m"),
                                     (dict(m_i_kg=-0.01), "m_i_kg"),
                                     (dict(m_o_kg=0.0), "m_o_kg"),
                                     (dict(m_o_kg="heavy"), "m_o_kg")])
def test_bad_inputs_raise(fn, kw, name):
    args = dict(C, h_imp_m=1e-3)
    args.update(kw)
    with pytest.raises(ValueError, match=name):
        fn(**args)


@pytest.mark.parametrize("kw,name", [(dict(alpha=1.5), "alpha"), (dict(alpha=-0.1), "alpha"),
                                     (dict(c_d=-0.1), "c_d"), (dict(g=float("nan")), "g"),
                                     (dict(rho=0.0), "rho"), (dict(t_max=0.0), "t_max"),
                                     (dict(max_contacts=0), "max_contacts")])
def test_bad_params_raise(kw, name):
    with pytest.raises(ValueError, match=name):
        JumpParams(**kw)


def test_grazing_dip_between_samples_is_found():
    """A dip below zero entirely between two samples (all samples positive) is still a contact,
    and a maximum between samples is located exactly."""
    from snapjump_cli.jump.events import first_fall, maxima

    def F(t):
        return (t - 0.5) ** 2 - 1e-6

    def dF(t):
        return 2.0 * (t - 0.5)

    T = np.array([0.0, 0.3, 0.7, 1.0])
    Fv, dFv = F(T), dF(T)
    assert np.all(Fv > 0.0)
    t = first_fall(F, dF, T, Fv, dFv)
    assert t == pytest.approx(0.5 - 1e-3, rel=1e-12)

    def G(t):
        return -F(t)

    def dG(t):
        return -dF(t)

    T2 = np.array([0.0, 0.45, 0.7, 1.0])  # the maximum at 0.5 lies between two samples
    out = maxima(G, dG, T2, G(T2), dG(T2))
    assert len(out) == 1
    assert out[0][0] == pytest.approx(0.5, abs=1e-7) and out[0][1] == pytest.approx(1e-6, rel=1e-9)


@pytest.mark.parametrize("m,c,k", [(0.01, 0.4, 600.0), (0.01, 0.0, 600.0), (0.01, 2.0, 10.0),
                                   (0.01, 0.4, 4.0), (0.01, 0.4, 4.0 * (1 + 1e-9))])
def test_oscillator_sup_bound_is_a_nonincreasing_envelope(m, c, k):
    """The resting-phase certificate: sup_future |x| <= bound, and the bound never grows."""
    from snapjump_cli.jump.closed_form import Oscillator

    osc = Oscillator(m, c, k)
    rng = np.random.default_rng(0)
    T = 40.0 * osc.dt * 64
    t = np.linspace(0.0, T, 20001)
    for _ in range(20):
        x0, v0 = rng.normal(size=2) * (1.0, math.sqrt(k / m))
        _, x, v = osc.xv(x0, v0, t)
        b = np.array([osc.sup_bound(xi, vi) for xi, vi in zip(x[::50], v[::50])])
        assert np.all(np.diff(b) <= 1e-12 * b[0])
        suffix_max = np.maximum.accumulate(np.abs(x)[::-1])[::-1]
        assert np.all(suffix_max[::50] <= b * (1 + 1e-12) + 1e-14 * abs(x0))


def test_heavily_damped_weak_design_settles_and_is_certified():
    for fn in (jump_height, jump_height_ode):
        r = fn(h_imp_m=0.0, params=JumpParams(c_d=2.0), **A_LIKE)
        assert r.complete and not r.jumped and not r.lift_off and r.y_jump_m == 0.0



def _flight_phases(design: dict, p: JumpParams) -> tuple:
    """The model of ``design`` and flight phases to probe it with: those of a real trajectory, and
    two without gravity or centre-of-mass motion whose ``y_i`` is only the oscillator's
    ``x0 (exp(-sig t) C(t) - 1)`` and whose ``v_i`` is only ``v0 exp(-sig t) C(t)`` (so a last-bit
    change in those terms is not lost in the sum)."""
    from snapjump_cli.jump.closed_form import Phase, PhaseModel

    traj = jump_trajectory(h_imp_m=2e-3, params=p, **design)
    phases = [ph for ph in traj._phases if ph.kind == "flight" and ph.t1 > ph.t0][:3]
    md = traj._model
    md0 = PhaseModel(md.k, md.m_i, md.m_o, JumpParams(c_d=p.c_d, g=0.0))
    osc, r, x0, v0 = md0.rel, md0.r, 1e-2, 1.0
    only_x = Phase("flight", 0.0, 1.0, 0.0, r * osc.sig * x0, x0, -osc.sig * x0)
    only_v = Phase("flight", 0.0, 1.0, 0.0, -r * v0, -osc.sig * v0 / osc.w0sq, v0)
    return [(md, ph, ph.t1 - ph.t0) for ph in phases] + [(md0, only_x, 0.0), (md0, only_v, 0.0)]


@pytest.mark.parametrize("design,p", [(C, JumpParams()), (D, JumpParams()), (D, JumpParams(c_d=0.0)),
                                      (OVER, JumpParams()), (_critical(), JumpParams())],
                         ids=["C", "D", "D undamped", "overdamped", "critical"])
def test_scalar_flight_equals_the_general_form_to_the_bit(design, p):
    """The root finders' scalar ``y_i(t)``, ``v_i(t)`` and state (``PhaseModel.flight_at``) give
    exactly the numbers of the general form ``PhaseModel.flight`` at the same scalar time, and agree
    with its array form (which rounds squares differently: within a few ulp)."""
    rng = np.random.default_rng(1)
    for md, ph, span in _flight_phases(design, p):
        at = md.flight_at(ph)
        y_at, v_at = at.y, at.v
        span = span or 100.0 * md.rel.dt
        ts = np.concatenate([[0.0, span], rng.uniform(0.0, span, 1500),
                             rng.uniform(0.0, 20.0 * md.rel.dt, 500)])
        general = [md.flight(ph, t) for t in ts.tolist()]
        ys = np.array([y_at(t) for t in ts.tolist()])
        vs = np.array([v_at(t) for t in ts.tolist()])
        np.testing.assert_array_equal(ys, [float(g[0]) for g in general])
        np.testing.assert_array_equal(vs, [float(g[1]) for g in general])
        for t, g in zip(ts.tolist()[::10], general[::10]):
            assert at.state(t) == tuple(float(a) for a in g)
        Y, V, _, _ = md.flight(ph, ts)
        np.testing.assert_allclose(ys, Y, rtol=1e-12, atol=1e-15 * np.max(np.abs(Y)))
        np.testing.assert_allclose(vs, V, rtol=1e-12, atol=1e-15 * np.max(np.abs(V)))



def _answer_all(gen, evaluate):
    """Run a generator of requests ``(key, t)`` to its end, sending back ``evaluate(t)``."""
    try:
        _, t = next(gen)
        while True:
            _, t = gen.send(evaluate(t))
    except StopIteration as stop:
        return stop.value


def test_sampling_in_pieces_finds_the_first_fall_of_the_whole_chunk():
    """samples_to_fall (a chunk sampled in growing pieces up to the first fall) returns what
    first_fall finds on the whole chunk, whatever the piece sizes: here the first fall is a
    grazing dip between two positive samples, preceded by sampled minima that do not dip, and
    a piece boundary falls on each sample for some size."""
    from snapjump_cli.jump.events import Chunk, first_fall, samples_to_fall

    def F(t):  # minima at t = k + 1/2, the k-th at 0.05 - 0.006 k: the 9th dips below zero
        return 1.05 - 0.006 * np.floor(t) + np.cos(2.0 * np.pi * t)

    def dF(t):
        return -2.0 * np.pi * np.sin(2.0 * np.pi * t)

    def f(t):
        return float(F(t))

    def df(t):
        return float(dF(t))

    def yv(t):
        return F(t), dF(t)

    times = 0.0 + 0.075 * np.arange(1.0, 201.0)
    T_prev = np.array([0.0])
    T = np.concatenate([T_prev, times])
    whole = first_fall(f, df, T, F(T), dF(T))
    assert whole is not None and 9.0 < whole < 9.5 and np.all(F(T[T <= whole]) > 0.0)
    for piece, then in [(p, 2 * p) for p in range(1, 160)] + [(1, 1), (7, 100), (130, 3)]:
        scan = samples_to_fall(None, f, df, Chunk(times, 0.0, 1.0, 0, math.inf), T_prev,
                                F(T_prev), dF(T_prev), piece, then)
        Tp, Fp, dFp, t = _answer_all(scan, yv)
        assert t == whole, piece
        assert Tp[-1] >= whole and np.array_equal(Tp, T[:Tp.size])
        assert np.array_equal(Fp, F(Tp)) and np.array_equal(dFp, dF(Tp))
    # no fall in the chunk: all of it sampled
    scan = samples_to_fall(None, f, df, Chunk(times[:100], 0.0, 1.0, 0, math.inf), T_prev,
                            F(T_prev), dF(T_prev), 7, 14)
    Tp, Fp, _, t = _answer_all(scan, yv)
    assert t is None and np.array_equal(Tp, T[:101]) and np.array_equal(Fp, F(Tp))


def _time_grid_materialised(h0: float, dt: float, t_end: float):
    """The time grid as whole arrays (what time_grid's chunks stand for)."""
    from snapjump_cli.jump.events import CHUNK

    h0 = min(h0, dt)
    n_geo = int(math.ceil(math.log2(dt / h0))) if h0 < dt else 0
    head = np.cumsum(h0 * 2.0 ** np.arange(n_geo))
    last = float(head[-1]) if head.size else 0.0
    chunk = np.concatenate([head, last + dt * np.arange(1, CHUNK + 1)])
    while True:
        sel = chunk[chunk < t_end]
        if sel.size < chunk.size:
            yield np.append(sel, t_end)
            return
        yield chunk
        chunk = float(chunk[-1]) + dt * np.arange(1, CHUNK + 1)


def test_time_grid_chunks_hold_the_materialised_times():
    """time_grid's chunks make their times on demand, piece by piece: the same numbers, chunks
    and end as the whole arrays, and count_before counts them."""
    from snapjump_cli.jump.events import time_grid

    rng = np.random.default_rng(3)
    dt = 1e-4
    ends = [0.5 * dt, dt, 3e-3, 0.4096, 0.4096 + 17 * dt, 1.3, float(4 * 4096 * dt + 5 * dt)]
    for h0 in (1e-4 * dt, dt, 2 * dt, 3.3e-9):
        for t_end in ends + list(rng.uniform(0.0, 1.5, 5)):
            chunks = list(time_grid(h0, dt, t_end))
            whole = list(_time_grid_materialised(h0, dt, t_end))
            assert [c.size for c in chunks] == [w.size for w in whole]
            for c, w in zip(chunks, whole):
                assert np.array_equal(c.times(0, c.size), w)
                cuts = sorted({0, c.size, *rng.integers(0, c.size + 1, 6).tolist()})
                assert np.array_equal(np.concatenate([c.times(a, b) for a, b in zip(cuts, cuts[1:])]), w)
                for t in [*w[rng.integers(0, w.size, 4)].tolist(), 0.0, t_end, 2.0, math.inf]:
                    assert c.count_before(t) == int(np.sum(w < t))


@pytest.mark.parametrize("design,h,p", [(C, 5e-3, JumpParams()), (D, 0.0, JumpParams()),
                                        (B_LIKE, 1e-3, JumpParams()), (OVER, 0.2e-3, JumpParams()),
                                        (C, 3e-3, JumpParams(alpha=1.0, t_max=0.3))],
                         ids=["C", "D h=0", "B-like", "overdamped", "C elastic"])
def test_flight_scan_in_pieces_equals_the_whole_chunk(monkeypatch, design, h, p):
    """The flight scan samples a chunk of the time grid in growing pieces up to the first
    impact (samples_to_fall), the first one up to where the impact must have come; any first
    piece size, down to one sample, gives exactly the contacts, apexes and phases that sampling
    whole chunks at once gives."""
    import snapjump_cli.jump.events as je

    def run() -> tuple:
        traj = jump_trajectory(h_imp_m=h, params=p, **design)
        return (traj.result, traj.contact_times, traj.apexes, traj._phases)

    as_is = run()
    assert as_is[1] and as_is[2]
    monkeypatch.setattr(je.PhaseModel, "fall_time_bound", lambda self, ph: math.inf)
    monkeypatch.setattr(je, "_PIECE_FIRST", 10**6)
    assert run() == as_is  # whole chunks
    monkeypatch.setattr(je.PhaseModel, "fall_time_bound", lambda self, ph: 0.0)
    for piece in (1, 3, 256):  # pieces of 2, then piece, 2 piece, ...
        monkeypatch.setattr(je, "_PIECE_MIN", piece)
        assert run() == as_is


@pytest.mark.parametrize("name,design,h,p", CASES, ids=[c[0] for c in CASES])
def test_fall_time_bound_is_an_upper_bound(name, design, h, p):
    """Every flight reaches the ground by PhaseModel.fall_time_bound of its start (it sizes the
    first piece of the scan: a wrong bound costs time, not accuracy)."""
    traj = jump_trajectory(h_imp_m=h, params=p, **design)
    md = traj._model
    for ph, tc in zip([ph for ph in traj._phases if ph.kind == "flight"], traj.contact_times):
        assert ph.t1 - ph.t0 <= md.fall_time_bound(ph)


def test_index_scans_of_lists_equal_those_of_arrays():
    """The sign-change and sampled-extremum scans give the same indices on a list of floats (the
    short-array path) as on the array: ties, zeros, signed zeros and NaN included."""
    from snapjump_cli.jump.events import down_crossings, sampled_maxima, sampled_minima

    rng = np.random.default_rng(5)
    for _ in range(400):
        n = int(rng.integers(0, 40))
        a = rng.choice([-1.0, -0.0, 0.0, 0.5, 1.0, 2.0, np.nan], n) if rng.random() < 0.5 \
            else rng.normal(size=n)
        for scan in (down_crossings, sampled_minima, sampled_maxima):
            if scan is not down_crossings and n < 3:
                continue
            assert list(scan(a.tolist())) == [int(k) for k in scan(a)], (scan.__name__, a)
