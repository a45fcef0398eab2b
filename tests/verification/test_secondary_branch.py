"""A followed branch that loses stability outside its harmonics (snapjump_cli.fe.branch.secondary).

Two caps at one element through the thickness, whose first harmonic to go unstable is 3 and whose
branch (harmonics 0, 3, 6) rises far beyond the axisymmetric V* but, in the model with every
harmonic 0..6, is unstable on the way in the other Bloch class (1, 2, 4, 5):

* the Fig. S16 ring-roller cap (70 deg, eta 12.5): the branch rises from its bifurcation and
  loses stability in harmonic 2 on the way. The secondary bifurcation is bracketed by two
  consecutive path points (no extra unstable mode before, one after) and located where the extra
  eigenvalue is zero; the branch leaving it starts on the first branch, its states are equilibria
  of the full model, and the amplitude of the other harmonics grows along it.
* the clamped cap (30 deg, eta 80): the branch turns back in volume at once (a fold at its
  bifurcation), and the state on the branch that the actuator jumps to at that volume is already
  unstable in harmonic 2. The jump goes on outside the branch: the lower state is found at the
  fold's volume by an energy descent with every harmonic, it is stable there, it releases energy
  and it is not on the branch; the row keys and the note say what happened, and the plot draws
  it.
"""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_cli.fe.branch.metrics import branch_curve
from snapjump_cli.fe.branch.bifurcation import default_harmonics, locate_bifurcation
from snapjump_cli.fe.branch.trace import follow_branch
from snapjump_cli.fe.branch.followed import followed_metrics
from snapjump_cli.fe.stability.harmonics import check_harmonics
from snapjump_cli.fe.branch.secondary import (
    LOCATE_STEP_FRACTION,
    extra_harmonics,
    follow_secondary,
    jump_before,
    lift,
    reached_along,
    unstable_modes,
    visited_points,
)
from snapjump_cli.fe.stability.eigen import extra_eigen
from snapjump_cli.fe.solve import solve_scene
from snapjump_cli.geometry.caps import CapScene
from snapjump_cli.settings import MeshSettings, SolverSettings


def _solved(theta, eta, bc):
    res = solve_scene(CapScene(theta_deg=theta, eta=eta, bc=bc), MeshSettings(nt=1, aspect=2.0), SolverSettings())
    chk = check_harmonics(res, 4)
    assert chk.asym_first and chk.asym_n == 3
    return res, chk


@pytest.fixture(scope="module")
def located():
    """The S16 ring-roller cap: the branch, and the first steps of the branch leaving it."""
    res, chk = _solved(70.0, 12.5, "ring-roller")
    fr = follow_branch(res, locate_bifurcation(res, 3), default_harmonics(3, 6))
    fs, c, sec = follow_secondary(res, fr, max_steps=8)
    return res, fr, fs, sec


@pytest.fixture(scope="module")
def head(located):
    """The S16 branch traced only up to its first volume limit (the actuator mode's trace, unchecked)."""
    res, fr, fs, sec = located
    return follow_branch(res, fr.bif, list(fr.model.hn), stop_at_upper=True)


@pytest.fixture(scope="module")
def jumped():
    """The clamped cap: the followed answer."""
    res, chk = _solved(30.0, 80.0, "clamped")
    answer = followed_metrics(res, chk, N=6)
    out, fs = answer.values, answer.branch
    res.metrics.update(chk.as_row())
    return res, out, fs


def test_the_secondary_bifurcation_is_bracketed_and_located(located):
    res, fr, fs, sec = located
    assert sec is not None and fs.kind != "jump"
    assert list(fr.model.hn) == [0, 3, 6] and list(fs.model.hn) == list(range(7))
    full = fs.model
    assert sec.n in extra_harmonics(fr.model, full)
    pts = fr.path.points

    def extra(pt):
        return unstable_modes(full, lift(fr.model, full, pt.u), pt.p) - unstable_modes(fr.model, pt.u, pt.p)

    # the actuator passes through both points of the bracket, the first stable outside the branch
    assert {sec.index, sec.index + 1} <= set(visited_points(fr, sec.index + 1)) | {0}
    assert extra(pts[sec.index]) == 0 and extra(pts[sec.index + 1]) > 0
    ex = extra_harmonics(fr.model, full)
    e_a = extra_eigen(full, lift(fr.model, full, pts[sec.index].u), pts[sec.index].p, ex)[0]
    e_b = extra_eigen(full, lift(fr.model, full, pts[sec.index + 1].u), pts[sec.index + 1].p, ex)[0]
    e_c = extra_eigen(full, lift(fr.model, full, sec.point.u), sec.point.p, ex)[0]
    # located to LOCATE_STEP_FRACTION of the eigenvalue's change over the step (or 1e-7 of e_a)
    assert e_a > 0 > e_b and abs(e_c) < max(1e-7 * e_a, LOCATE_STEP_FRACTION * (e_a - e_b))
    assert fr.states.upper is not None and sec.index < fr.states.k_before  # before the branch's own snap


def test_the_located_point_is_the_root_to_the_step_fraction(located, monkeypatch):
    """The root finding stops at LOCATE_STEP_FRACTION of the eigenvalue's change over the step: the
    point lies within about that fraction of the step's volume change from the one located with the
    eigenvalue's tolerance alone (1e-7 of its value at the stable end), on the same step."""
    import snapjump_cli.fe.branch.secondary as secondary
    from snapjump_cli.fe.branch.secondary import SecondaryCheck, locate_secondary

    res, fr, fs, sec = located
    full = fs.model
    pts = fr.path.points
    monkeypatch.setattr(secondary, "LOCATE_STEP_FRACTION", 0.0)
    tight = locate_secondary(fr, SecondaryCheck(N=int(full.hn[-1]), first=0), full, first=sec.index + 1)
    assert tight is not None and tight.index == sec.index and tight.n == sec.n
    L3 = fr.model.L**3
    dV = abs(fr.model.volume(pts[sec.index + 1].u) - fr.model.volume(pts[sec.index].u)) * L3
    assert abs(tight.V_m3 - sec.V_m3) <= 2.0 * LOCATE_STEP_FRACTION * dV


def test_a_bracket_started_inside_the_step_finds_the_same_point(located):
    """locate_secondary(start=...): the bracket of a jump's landing state, stable outside the
    branch, between two path points (the state a micro-fold traced through lands on): here a state
    of the located step itself, before the point, finds that point again."""
    from snapjump_cli.fe.branch.secondary import SecondaryCheck, locate_secondary

    res, fr, fs, sec = located
    full = fs.model
    pts = fr.path.points
    a, b = pts[sec.index], pts[sec.index + 1]
    ex = extra_harmonics(fr.model, full)
    for frac in (0.5, 0.25, 0.1, 0.02):  # a state of the step before the point (stable outside)
        start = fr.tracer.step_between(a, b, frac * (b.s - a.s))
        if start is not None and extra_eigen(full, lift(fr.model, full, start.u), start.p, ex)[0] > 0:
            break
    else:
        pytest.fail("no state of the step before the secondary point")
    again = locate_secondary(fr, SecondaryCheck(N=int(full.hn[-1]), first=0), full, first=sec.index + 1, start=start)
    assert again is not None and again.n == sec.n and again.index == sec.index
    assert again.V_m3 == pytest.approx(sec.V_m3, rel=1e-9) and again.p_Pa == pytest.approx(sec.p_Pa, rel=1e-7)
    late = fr.tracer.step_between(a, b, 0.999 * (b.s - a.s))  # a start past the point: no bracket
    if extra_eigen(full, lift(fr.model, full, late.u), late.p, ex)[0] < 0:
        assert locate_secondary(fr, SecondaryCheck(N=int(full.hn[-1]), first=0), full, first=sec.index + 1,
                                start=late) is None


def test_the_actuator_mode_traces_the_branch_only_to_its_first_fold_and_finds_the_same_point(located, head):
    """follow_mode "actuator" (the default): the branch of n_c >= 2 is traced only up to its first
    volume limit before the check (the states the actuator passes through), and the point and the
    branch leaving it are those of the full trace, which passes through the same states first."""
    from snapjump_cli.fe.branch.trace import UPPER_LOCATED

    res, fr, fs, sec = located
    st = head.states
    assert head.path.stop_reason == UPPER_LOCATED and st.upper is not None and st.lower is None
    assert head.metrics.get("dE_J") is None  # no snap: its lower state was never sought
    k = st.k_before
    assert k == fr.states.k_before and len(head.path.points) == k + 2 < len(fr.path.points)
    assert st.upper.zeta[0] == fr.states.upper.zeta[0]
    for a, b in zip(head.path.points, fr.path.points[: k + 2]):  # the same states, bit for bit
        assert np.array_equal(a.u, b.u) and a.p == b.p
    hs, chk, hsec = follow_secondary(res, head, max_steps=8)
    assert hsec is not None and (hsec.n, hsec.index) == (sec.n, sec.index)
    assert hsec.V_m3 == sec.V_m3 and hsec.p_Pa == sec.p_Pa
    assert all(np.array_equal(a.u, b.u) for a, b in zip(hs.path.points, fs.path.points))


def test_checked_while_traced_the_branch_stops_at_the_first_unstable_state_and_finds_the_same_point(located, head):
    """The actuator mode checks the branch while it is traced (``watch``, every 5th state passed
    through, as the check after the trace picks them): the trace stops at the first state checked
    unstable outside the branch, before its fold, and the check, the point and the branch leaving it
    are those of the trace to the fold (the same states, their counts reused, not made twice)."""
    from snapjump_cli.fe.branch.secondary import StabilityWatch, branch_stability, stability_watch
    from snapjump_cli.fe.branch.trace import UNSTABLE_OUTSIDE

    res, fr, fs, sec = located
    watched = follow_branch(res, fr.bif, list(fr.model.hn), stop_at_upper=True, watch=stability_watch(u_axi=fr.bif.u))
    w = watched.watch
    assert isinstance(w, StabilityWatch) and watched.path.stop_reason == UNSTABLE_OUTSIDE
    assert watched.states.upper is None
    n = len(watched.path.points)
    assert sec.index < n - 1 < head.states.k_before
    for a, b in zip(watched.path.points, head.path.points):  # the same states, bit for bit
        assert np.array_equal(a.u, b.u) and a.p == b.p
    chk_h = branch_stability(head, stride=5, stop_at_first=True)
    chk_w = branch_stability(watched, stride=5, stop_at_first=True, full=w.full, counts=w.counts)
    assert chk_w.index == chk_h.index and chk_w.outside == chk_h.outside and chk_w.own == chk_h.own
    assert sorted(w.counts) == chk_w.index and chk_w.index[-1] == n - 1
    ws, _, wsec = follow_secondary(res, watched, max_steps=8)
    assert wsec is not None and (wsec.n, wsec.index, wsec.V_m3, wsec.p_Pa) == (sec.n, sec.index, sec.V_m3, sec.p_Pa)
    assert all(np.array_equal(a.u, b.u) for a, b in zip(ws.path.points, fs.path.points))


def test_the_own_count_is_made_only_where_modes_lie_outside_and_the_check_decides_the_same(located, head,
                                                                                          monkeypatch):
    """The check counts a state's unstable modes in the branch's own model only where some lie
    outside it (``OWN_WHERE_OUTSIDE``): the states, the counts outside and the first state unstable
    there are those of the check that counts both everywhere, the own counts where made equal, and
    the branch's model is linearised for them only at states unstable outside."""
    from snapjump_cli.fe.branch import secondary

    calls = []
    own_count = secondary.unstable_modes
    monkeypatch.setattr(secondary, "unstable_modes", lambda *a: calls.append(a) or own_count(*a))
    lazy = secondary.branch_stability(head, stride=2)
    n_lazy = len(calls)
    monkeypatch.setattr(secondary, "OWN_WHERE_OUTSIDE", False)
    every = secondary.branch_stability(head, stride=2)
    assert lazy.index == every.index and lazy.outside == every.outside and lazy.first == every.first
    assert lazy.first is not None and any(o == 0 for o in lazy.outside)  # both kinds of state checked
    assert all((o == 0) == (w is None) for o, w in zip(lazy.outside, lazy.own))
    assert all(w == e for w, e in zip(lazy.own, every.own) if w is not None)
    assert n_lazy == sum(o != 0 for o in lazy.outside) < len(calls) - n_lazy == len(every.index)


def test_the_secondary_branch_leaves_along_the_other_harmonics(located):
    res, fr, fs, sec = located
    full = fs.model
    start = fs.path.points[0]
    np.testing.assert_allclose(start.u, lift(fr.model, full, sec.point.u), rtol=0, atol=1e-14)
    others = extra_harmonics(fr.model, full)

    def amplitude(u):
        return max(float(np.abs(full.harmonic_part(u, n)).max()) for n in others)

    amps = [amplitude(pt.u) for pt in fs.path.points[:6]]
    assert len(amps) == 6 and amps[0] == 0.0 and all(b > a for a, b in zip(amps, amps[1:]))
    for pt in fs.path.points[1:6]:  # equilibria of the model with every harmonic
        lin = full.linearize(pt.u, pt.p)
        assert np.linalg.norm(lin.R) < 1e-6 * abs(pt.p) * np.linalg.norm(lin.g)


def test_the_arbiter_starts_a_secondary_snap_on_the_branch_it_leaves_just_past_the_point(located):
    """``bench.arbiter`` starts the damped motion of a subcritical secondary snap from the parent
    branch's state at ``(1 + past) V_sec``: an equilibrium of the model with every harmonic at that
    volume, on the parent branch (no other harmonics), unstable outside it, next to the point."""
    from types import SimpleNamespace

    from bench.arbiter import past_bifurcation

    res, fr, fs, sec = located
    full, up = fs.model, fs.path.points[0]
    stub = SimpleNamespace(model=full, tracer=fs.tracer, parent=fr, states=SimpleNamespace(upper=up))
    pts = fr.path.points
    V_next = float(pts[sec.index + 1].zeta[0]) * float(fr.tracer.sc[0]) / float(fs.tracer.sc[0])
    V1 = 0.5 * (float(up.zeta[0]) + V_next)  # past the point, inside the bracket's step
    st = past_bifurcation(res, stub, V1)
    lin = full.linearize(st.u, st.p)
    assert np.linalg.norm(lin.R) < 1e-6 * abs(st.p) * np.linalg.norm(lin.g)
    assert abs(float(fs.tracer.zeta(st.u, st.p)[0][0]) - V1) < 1e-8 * V1
    assert max(float(np.abs(full.harmonic_part(st.u, n)).max()) for n in extra_harmonics(fr.model, full)) == 0.0
    ex = extra_harmonics(fr.model, full)
    assert extra_eigen(full, st.u, st.p, ex)[0] < 0.0
    assert 0.0 < np.linalg.norm(st.u - up.u) < np.linalg.norm(lift(fr.model, full, pts[sec.index + 1].u) - up.u)


def test_a_jump_onto_a_state_unstable_outside_the_branch_goes_on_outside_it(jumped):
    res, out, fs = jumped
    fr, sec, full = fs.parent, fs.secondary, fs.model
    assert fs.kind == "jump" and fr.first_kind == "subcritical"
    # the fold the branch's trace located and traced through, and the state it lands on
    pts = fr.path.points
    jump = jump_before(fr, next(j for j in visited_points(fr, len(pts) - 1) if j > fr.folds[0].k))
    assert jump is not None and sec.point is jump.landing and sec.index == jump.k
    V_fold = fr.model.volume(jump.upper.u)
    # a volume high: at or past the point before it (here the bifurcation point itself, where the
    # subcritical branch turns back at once), above the point after it
    assert V_fold >= fr.model.volume(pts[jump.k].u) and V_fold > fr.model.volume(pts[jump.k + 1].u)
    assert fr.model.volume(jump.landing.u) == pytest.approx(V_fold, rel=1e-8)  # the landing: the same volume,
    assert fr.model.energy(jump.landing.u) < fr.model.energy(jump.upper.u)  # further along, lower
    after = [j for j in visited_points(fr, len(pts) - 1) if j > jump.k]
    assert after and not reached_along(fr, after[0])  # the next point passed through is reached by the jump
    assert unstable_modes(full, lift(fr.model, full, sec.point.u), sec.point.p) > unstable_modes(
        fr.model, sec.point.u, sec.point.p)
    up, lo = fs.states.upper, fs.states.lower
    assert full.volume(up.u) == pytest.approx(V_fold, rel=1e-12)  # the jump starts at the fold itself
    assert lo is not None and fs.states.lower_method == "descent"
    assert full.volume(lo.u) == pytest.approx(V_fold, rel=1e-8)  # and ends at its volume
    lin = full.linearize(lo.u, lo.p)
    assert unstable_modes(full, lo.u, lo.p) == 0  # stable with every harmonic
    assert np.linalg.norm(lin.R) < 1e-6 * abs(lo.p) * np.linalg.norm(lin.g)
    assert max(float(np.abs(full.harmonic_part(lo.u, n)).max()) for n in extra_harmonics(fr.model, full)) > 1e-3 * \
        float(np.abs(full.amplitudes(lo.u)).max())  # off the branch
    assert full.energy(up.u) - full.energy(lo.u) > 0


def test_the_row_says_what_happened(jumped):
    res, out, fs = jumped
    sec = fs.secondary
    assert out["followed"] and out["follow_n"] == 3 and out["follow_N"] == 6 and out["follow_kind"] == "jump"
    assert out["follow_sec_n"] == sec.n and out["follow_sec_V_m3"] == pytest.approx(sec.V_m3, rel=1e-12)
    assert "jumps to on the branch is unstable in harmonic" in out["follow_note"]
    # n_c = 3: the mode's two signs are not mirror images; the jump is landed by the descent along its sign
    assert "(energy descent)" in out["follow_note"] and "fixed-volume path" not in out["follow_note"]
    assert out["dE_J"] > 0 and out["dy_pole_m"] > 0
    from snapjump_cli.fe.branch.trace import LEFT_AT_LANDING

    own = fs.parent.metrics.get("V_star_m3")  # the branch's own volume limit, if traced: the jump comes first
    # (the actuator mode stops the branch where the jump leaves it: no volume limit of its own)
    assert (own is None and fs.parent.path.stop_reason == LEFT_AT_LANDING) or out["V_star_m3"] < own
    bc = branch_curve(fs)
    assert bc["n_sec"] == sec.n and len(bc["V_m3"]) == sec.index + 1 + len(fs.path.points)  # up to the fold
    assert bc["V_sec_m3"] is None and bc["landing_V_m3"] == sec.V_m3
    # the kinds of both branches: the n = 3 branch's own (how it left the axisymmetric path), then the jump
    assert bc["kind"] == "jump" and bc["parent_kind"] == (fs.parent.first_kind or fs.parent.kind) != "jump"
    from snapjump_cli.commands.curve import _text

    text = _text(None, dict(res.metrics, **out))
    followed = next(ln for ln in text.splitlines() if ln.startswith("followed branch"))
    assert "n = 3 (harmonics up to 6)" in followed and "jump" not in followed
    sec_line = next(ln for ln in text.splitlines() if ln.startswith("secondary"))
    assert "the state it jumps to there is unstable in n = " in sec_line and "loses stability" not in sec_line


def test_the_plot_draws_both_branches_and_the_secondary_point(jumped, located, tmp_path, monkeypatch):
    pytest.importorskip("matplotlib")
    from snapjump_cli.viz import figures
    from snapjump_cli.viz.figures import plot_pv_curve

    seen: list[list[str]] = []
    save = figures._save

    def keep_legend(fig, path, dpi):  # the legend's entries of each figure as it is saved
        legends = [*fig.legends, *(ax.get_legend() for ax in fig.axes if ax.get_legend())]  # the figure's or an axes'
        seen.append([t.get_text() for lg in legends for t in lg.get_texts()])
        return save(fig, path, dpi)

    monkeypatch.setattr(figures, "_save", keep_legend)

    def labels(png):
        assert png.stat().st_size > 10_000
        return seen[-1]

    res, out, fs = jumped
    png = plot_pv_curve(res.curve, dict(res.metrics, **out), tmp_path / "pv.png", title="jump", branch=branch_curve(fs))
    got = labels(png)
    assert any("then a jump" in t for t in got) and any(t.startswith("the fold's jump lands here") for t in got)
    assert not any(t.startswith("secondary bifurcation") for t in got)
    res, fr, fs, sec = located  # a branch leaving at a located point, not traced to a snap here
    bc = branch_curve(fs)
    assert len(bc["V_m3"]) == sec.index + 2 + len(fs.path.points) and bc["V_sec_m3"] == sec.V_m3
    metrics = dict(res.metrics, dE_J=res.metrics["dE_J"], axisym_dE_J=res.metrics["dE_J"])
    png = plot_pv_curve(res.curve, metrics, tmp_path / "pv2.png", title="located", branch=bc)
    got = labels(png)
    assert "secondary bifurcation (n = 2)" in got and not any("lands here" in t for t in got)


def test_the_fixed_volume_path_from_the_jumps_landing_ends_where_the_damped_motion_comes_to_rest(jumped):
    """The jump's landing by the fixed-volume path (``jump_off_branch(volume_path=True)``, the
    actuator mode's for an even ``n_c``; here the mechanics on the clamped cap's ``n_c = 3`` jump):
    the path that leaves the unstable landing state along its unstable mode at the fold's volume
    ends on an equilibrium at that volume, stable with every harmonic and below the landing state;
    the damped motion at that volume from the landing state, kicked the way the path went along
    the mode, comes to rest on the same state (the arbiter, snapjump_cli.fe.branch.dynamics)."""
    from snapjump_cli.fe.axisym.lower_state import snap_at_fixed_volume
    from snapjump_cli.fe.branch.dynamics import damped_snap, lowest_frequency
    from snapjump_cli.fe.continuation import PathPoint

    res, out, fs = jumped
    fr, sec, full, tr = fs.parent, fs.secondary, fs.model, fs.tracer
    L, p = lift(fr.model, full, sec.point.u), sec.point.p
    eig, mode = extra_eigen(full, L, p, extra_harmonics(fr.model, full))
    assert eig < 0.0
    unit = mode / np.linalg.norm(mode)
    at_L = PathPoint(L, p, tr.zeta(L, p)[0], fs.states.upper.tangent, unit / tr.alpha, 0.0, 0.0)
    low, msg = snap_at_fixed_volume(tr, at_L)  # (n_c = 3: the mode's two signs are not mirror images)
    assert low is not None, msg
    assert msg.startswith("fixed-volume path (mode control)")
    V_fold = full.volume(fs.states.upper.u)
    assert full.volume(low.u) == pytest.approx(V_fold, rel=1e-8)
    assert unstable_modes(full, low.u, low.p) == 0
    assert full.energy(low.u) < full.energy(L)
    lin = full.linearize(low.u, low.p)
    assert np.linalg.norm(lin.R) < 1e-6 * abs(low.p) * np.linalg.norm(lin.g)
    way = float(np.sign(unit @ (low.u - L)))
    omega = lowest_frequency(tr, low.u, low.p)
    ds = damped_snap(tr, at_L, way * mode, omega, zeta=1.0, steps_per_period=10, rest=1e-6)
    assert ds.state is not None, ds.message
    assert np.linalg.norm(ds.state.u - low.u) < 1e-6 * np.linalg.norm(low.u)


@pytest.fixture(scope="module")
def jumped_even():
    """The clamped cap (30 deg, eta 50), ``n_c = 2``: the followed answer (actuator mode)."""
    res = solve_scene(CapScene(theta_deg=30.0, eta=50.0, bc="clamped"), MeshSettings(nt=1, aspect=2.0),
                      SolverSettings())
    chk = check_harmonics(res, 4)
    assert chk.asym_first and chk.asym_n == 2
    answer = followed_metrics(res, chk, N=8)
    return res, answer.values, answer.branch


def test_the_actuator_mode_does_not_trace_past_a_landing_the_jump_leaves(jumped_even):
    """A branch of ``n_c = 2`` whose first step is subcritical is traced through its micro-folds
    (the check of the branch's first states finds nothing to stop at); in the actuator mode the
    trace stops at the first micro-fold's landing that is unstable outside the branch
    (``follow_branch(settle=leaves_branch(...))``, :data:`~snapjump_cli.fe.branch.trace.LEFT_AT_LANDING`):
    the branch has no snap of its own (the reference traces it to one, 121 points, and searches
    its lower state), and the jump off the branch goes on from that landing (the same answer, bit
    for bit: a scratch comparison)."""
    from snapjump_cli.fe.branch.secondary import leaves_branch

    res, out, fs = jumped_even
    assert out["followed"] and out["follow_kind"] == "jump"
    from snapjump_cli.fe.branch.trace import LEFT_AT_LANDING

    fr = fs.parent
    assert fr.first_kind == "subcritical" and fr.states.upper is None  # stopped: no snap of its own
    assert fr.path.stop_reason == LEFT_AT_LANDING
    land = fs.secondary.point  # the jump goes on from the landing of the branch's micro-fold,
    assert any(f.landing is land for f in fr.folds)
    leaves = leaves_branch(u_axi=fr.bif.u)(fr.model)
    assert leaves(land)  # one the actuator leaves at once (unstable outside the branch),
    e = fr.settle.eigen(land.u, land.p)  # (the trace's check computed its eigenpair: the jump takes it)
    assert e is not None and e[0] == fs.secondary.eig and leaves.eigen(land.u, land.p)[0] == e[0]
    # and the path ends within a few steps past it
    k = next(f.k for f in fr.folds if f.landing is land)
    assert len(fr.path.points) - 1 - k <= 30


def test_where_the_sphere_path_turns_back_the_jump_lands_where_the_descent_and_the_damped_motion_do(jumped_even,
                                                                                                   monkeypatch):
    """The actuator mode lands the ``n_c = 2`` jump on the axisymmetric inverted state at the
    fold's volume where that is stable with every harmonic
    (:func:`snapjump_cli.fe.branch.trace.axisym_inverted_state`, ``JUMP_AXISYM_FIRST``), as here:
    an equilibrium at the fold's volume, stable with every harmonic and below the landing state.
    The sphere path (:func:`snapjump_cli.fe.axisym.sphere_path.descend_on_spheres`) tried first
    instead finds no state (its minima on the spheres around the landing state turn back before any
    is an equilibrium) and the same state is taken after it; the energy descent from the landing
    state kicked along its unstable mode (as before, ``AXISYM_BEFORE_DESCENT = False``) comes to
    rest on the same state, and so does the damped motion at that volume (the arbiter) from the
    same kick."""
    import snapjump_cli.fe.branch.secondary as secondary
    import snapjump_cli.fe.branch.trace as trace
    from snapjump_cli.fe.branch.dynamics import damped_snap, lowest_frequency
    from snapjump_cli.fe.branch.metrics import AXISYM_LANDING
    from snapjump_cli.fe.continuation import PathPoint

    res, out, fs = jumped_even
    assert fs.kind == "jump" and fs.lower_solver == "axisymmetric path", fs.lower_note
    assert fs.lower_note.endswith(AXISYM_LANDING) and "sphere path" not in fs.lower_note  # (taken first)
    assert "to the axisymmetric inverted state" in out["follow_note"]
    monkeypatch.setattr(secondary, "JUMP_AXISYM_FIRST", False)
    sph = followed_metrics(res, check_harmonics(res, 4), N=8).branch
    assert sph.lower_note.startswith("sphere path: turned back") and sph.lower_note.endswith(AXISYM_LANDING)
    assert np.linalg.norm(sph.states.lower.u - fs.states.lower.u) <= 1e-12 * np.linalg.norm(fs.states.lower.u)
    monkeypatch.setattr(trace, "AXISYM_BEFORE_DESCENT", False)
    desc = followed_metrics(res, check_harmonics(res, 4), N=8).branch
    assert desc.lower_solver == "energy-descent" and "descent converged" in desc.lower_note
    assert np.linalg.norm(desc.states.lower.u - fs.states.lower.u) < 1e-8 * np.linalg.norm(fs.states.lower.u)
    fr, sec, full, tr = fs.parent, fs.secondary, fs.model, fs.tracer
    low, up = fs.states.lower, fs.states.upper
    L, p = lift(fr.model, full, sec.point.u), sec.point.p
    assert full.volume(L) == pytest.approx(full.volume(up.u), rel=1e-12)  # (the landing is at the fold's volume)
    eig, mode = extra_eigen(full, L, p, extra_harmonics(fr.model, full))
    assert eig < 0.0
    assert full.volume(low.u) == pytest.approx(full.volume(up.u), rel=1e-8)
    assert unstable_modes(full, low.u, low.p) == 0
    assert full.energy(low.u) < full.energy(L)
    unit = mode / np.linalg.norm(mode)
    way = float(np.sign(unit @ (low.u - L)))
    at_L = PathPoint(L, p, tr.zeta(L, p)[0], up.tangent, unit / tr.alpha, 0.0, 0.0)
    ds = damped_snap(tr, at_L, way * mode, lowest_frequency(tr, low.u, low.p), zeta=1.0, steps_per_period=10,
                     rest=1e-6)
    assert ds.state is not None, ds.message
    assert np.linalg.norm(ds.state.u - low.u) < 1e-6 * np.linalg.norm(low.u)


def test_a_jump_landed_by_the_sphere_path():
    """``follow_strata_n2`` row 8's design on a coarser mesh (Q9, nt 1, aspect 3): its ``n = 2``
    branch folds and the state it jumps to is unstable in harmonic 1; the sphere path from that
    state lands the jump, on an equilibrium at the fold's volume (the landing state, a path point,
    lies 2e-4 above it), stable with every harmonic and below the fold."""
    from snapjump_cli.geometry.caps import Design

    res = solve_scene(Design(7.4, 80.0, 20.0 / 3.0, 90.0, 1.0), MeshSettings(order=2, nt=1, aspect=3.0),
                      SolverSettings(harmonics=4))
    chk = check_harmonics(res, 4)
    assert chk.asym_first and chk.asym_n == 2
    answer = followed_metrics(res, chk, mode="actuator")
    out, fs = answer.values, answer.branch
    assert fs.kind == "jump" and fs.lower_solver == "sphere-path", fs.lower_note
    assert fs.lower_note.startswith("sphere path: stable state") and "(sphere path)" in out["follow_note"]
    full, up, low = fs.model, fs.states.upper, fs.states.lower
    L = lift(fs.parent.model, full, fs.secondary.point.u)
    assert abs(full.volume(L) / full.volume(up.u) - 1.0) > 1e-5  # the spheres' volume is the landing state's
    assert full.volume(low.u) == pytest.approx(full.volume(up.u), rel=1e-8)
    assert unstable_modes(full, low.u, low.p) == 0
    assert full.energy(low.u) < full.energy(up.u)
    lin = full.linearize(low.u, low.p)
    assert np.linalg.norm(lin.R) < 1e-6 * abs(low.p) * np.linalg.norm(lin.g)
    assert out["dE_J"] > 0.0
