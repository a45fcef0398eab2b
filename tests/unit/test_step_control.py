"""Step control of the continuation: steps split instead of rejected, Newton stopped early."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from snapjump_cli.fe.continuation import ContinuationSettings
from snapjump_cli.fe.continuation.stepping import step_turn
from snapjump_cli.geometry.designs import get_design
from snapjump_cli.settings import MeshSettings, SolverSettings
from snapjump_cli.fe.solve import solve_scene

_FROM_SOLVER = ContinuationSettings.from_solver.__func__
_MESH = MeshSettings(order=2, nt=2, aspect=3.0)


def _solve(monkeypatch, name: str, solver: SolverSettings = SolverSettings(), **internal):
    orig = _FROM_SOLVER
    monkeypatch.setattr(ContinuationSettings, "from_solver",
                        classmethod(lambda cls, *a, **k: orig(cls, *a, **{**k, **internal})))
    return solve_scene(get_design(name), _MESH, solver)


@pytest.fixture(scope="module")
def design_D():
    mp = pytest.MonkeyPatch()
    try:
        new = _solve(mp, "D")
        old = _solve(mp, "D", split_steps=False, theta_max=math.inf)
    finally:
        mp.undo()
    return new, old


def test_split_steps_keep_the_answers_and_save_element_passes(design_D):
    new, old = design_D
    assert new.path.n_split > 0
    for k in ("dE_J", "dy_pole_m", "V_star_m3", "p_star_Pa", "h_imp_m"):
        assert new.metrics[k] == pytest.approx(old.metrics[k], rel=1e-6), k
    # dE along the path (Hermite quadrature over the points) agrees with the energy difference
    # as well as it did with every step kept whole
    gap_new, gap_old = (abs(r.metrics["dE_path_J"] / r.metrics["dE_J"] - 1) for r in (new, old))
    assert gap_new <= max(2 * gap_old, 1e-6)
    for k in ("self_crossing", "lower_state_method", "snaps"):
        assert new.metrics[k] == old.metrics[k], k
    assert new.model.n_assemblies < old.model.n_assemblies


def test_every_kept_step_turns_less_than_the_limit_and_its_arc_length_is_the_projection(design_D):
    new, _ = design_D
    tr = new.tracer
    pts = new.path.points
    assert len(pts) > 20
    for a, b in zip(pts[:-1], pts[1:]):
        assert step_turn(a, b, tr.alpha) <= tr.cfg.max_turn_deg
        # the Riks constraint of the step from a: the projection on a's tangent is the step length
        h = float(a.tangent @ (b.zeta - a.zeta)) + tr.alpha**2 * float(a.du_ds @ (b.u - a.u))
        assert b.s - a.s == pytest.approx(h, rel=1e-5, abs=1e-9)


def test_newton_gives_up_without_contraction_and_both_correctors_agree():
    res = solve_scene(get_design("C"), _MESH, SolverSettings())
    tr, M = res.tracer, res.model
    pts = res.path.points
    cfg0 = tr.cfg
    out = {}
    for ds in (1.5, 1.8, 2.1):  # steps far longer than the path allows here (ds ~ 0.1)
        for theta in (cfg0.theta_max, math.inf):
            for fused in (True, False):
                tr.cfg = dataclasses.replace(cfg0, fused=fused, theta_max=theta)
                n0 = M.n_assemblies
                new = tr.step(pts[10], ds, pts[9], tol=cfg0.tol_path, error_test=True)
                out[ds, theta, fused] = (new is None, M.n_assemblies - n0, None if new is None else new.zeta)
    tr.cfg = cfg0
    earlier = 0
    for ds in (1.5, 1.8, 2.1):
        rule, free = out[ds, cfg0.theta_max, True], out[ds, math.inf, True]
        assert rule[1] <= free[1]
        earlier += rule[0] and rule[1] < free[1]  # stopped without contraction, before max_newton
        for theta in (cfg0.theta_max, math.inf):  # the compiled and the Python corrector decide alike
            a, b = out[ds, theta, True], out[ds, theta, False]
            assert a[:2] == b[:2], (ds, theta)
            if a[2] is not None:
                np.testing.assert_allclose(a[2], b[2], rtol=1e-8)
    assert earlier >= 1


def _cubic_points(s_a: float, s_b: float):
    from snapjump_cli.fe.continuation import PathPoint

    V = lambda s: 1.0 + 2.0 * s - 3.0 * s**2 + 0.5 * s**3  # noqa: E731
    dV = lambda s: 2.0 - 6.0 * s + 1.5 * s**2  # noqa: E731
    pt = lambda s: PathPoint(np.zeros(1), 0.0, np.array([V(s), 0.0, 0.0]), np.array([dV(s), 0.0, 0.0]),  # noqa: E731
                             np.zeros(1), 0.0, s)
    return pt(s_a), pt(s_b), V, dV


def test_hermite_root_first_estimates_are_exact_on_a_cubic_volume():
    from snapjump_cli.fe.axisym.snap import _hermite_root

    a, b, V, dV = _cubic_points(0.2, 0.8)
    s_lim = (6.0 - math.sqrt(36.0 - 12.0)) / 3.0  # dV/ds = 0 at s = 0.367
    assert a.s + _hermite_root(a, b, 0.0, derivative=True) == pytest.approx(s_lim, rel=1e-12)
    a, b, V, dV = _cubic_points(0.5, 0.9)  # V falls monotonically here
    assert a.s + _hermite_root(a, b, V(0.7)) == pytest.approx(0.7, rel=1e-12)
    assert _hermite_root(a, b, V(0.5) + 10.0) is None  # not reached inside the step


def test_snap_states_are_located_to_their_tolerances(design_D):
    new, _ = design_D
    st = new.states
    assert abs(st.upper.tangent[0]) < 1e-7  # the volume limit: dV/ds = 0
    assert st.lower.zeta[0] == pytest.approx(st.upper.zeta[0], rel=1e-12)  # the lower state at V*


def test_easy_steps_grow_faster_and_a_failed_step_caps_the_next(monkeypatch):
    """``grow_easy``: after a step that converged in one Newton iteration and hardly turned, the next
    is ``grow_easy`` times longer (unless the turn aim or ``ds_max`` holds it); ``fail_cap``: after a
    failed corrector at ``ds_f``, the first step tried after the next accepted one is at most
    ``fail_cap ds_f`` (or the step just accepted). The answers stay those of the default control."""
    from snapjump_cli.fe.continuation import Tracer
    from snapjump_cli.fe.continuation.stepping import TURN_AIM

    tried = []
    orig_step = Tracer.step

    def step(self, pt, ds, prev=None, tol=None, error_test=False):
        new = orig_step(self, pt, ds, prev, tol, error_test)
        tried.append((pt, ds, new))
        return new

    ref = _solve(monkeypatch, "A")
    monkeypatch.setattr(Tracer, "step", step)
    res = _solve(monkeypatch, "A", grow_easy=8.0, fail_cap=0.8)
    cfg = res.tracer.cfg
    for k in ("dE_J", "dy_pole_m", "V_star_m3", "p_star_Pa"):
        assert res.metrics[k] == pytest.approx(ref.metrics[k], rel=1e-6), k
    easy = failed = 0
    for (pt, ds, new), (nxt_pt, nxt_ds, _) in zip(tried[:-1], tried[1:]):
        if new is None or nxt_pt is not new:
            continue
        ang = step_turn(pt, new, res.tracer.alpha)
        if new.newton == 1 and 0.0 < ang < 0.1 * cfg.max_turn_deg:
            expect = min(cfg.ds_max, ds * min(8.0, TURN_AIM * cfg.max_turn_deg / ang))
            assert nxt_ds <= expect * (1 + 1e-12)
            easy += nxt_ds == pytest.approx(expect, rel=1e-12)
    for i, (pt, ds_f, new) in enumerate(tried):
        if new is not None:
            continue
        acc = next((j for j in range(i + 1, len(tried) - 1) if tried[j][2] is not None
                    and tried[j + 1][0] is tried[j][2]), None)
        if acc is not None:
            failed += 1
            assert tried[acc + 1][1] <= max(0.8 * ds_f, tried[acc][1]) * (1 + 1e-12)
    assert easy >= 1 and failed >= 1  # design A: both rules act (2 failed correctors)


def test_steps_are_held_to_the_contraction_aimed_at(monkeypatch):
    """``theta_aim`` (the Python corrector, which measures a step's first contraction ``theta``,
    its second Newton correction over its first): after an accepted step the next is at most
    ``(theta_aim / theta)^(1/3)`` times as long; a step given up for its contraction
    (``theta > theta_max``) is retried at that fraction of its length, between 0.25 and 0.8. The
    answers stay those of the default control."""
    from snapjump_cli.fe.continuation import Tracer

    aim = 0.05
    tried = []
    orig_step = Tracer.step

    def step(self, pt, ds, prev=None, tol=None, error_test=False):
        new = orig_step(self, pt, ds, prev, tol, error_test)
        tried.append((pt, ds, new, self.last_theta))
        return new

    ref = _solve(monkeypatch, "A")
    monkeypatch.setattr(Tracer, "step", step)
    res = _solve(monkeypatch, "A", fused=False, theta_aim=aim)
    cfg = res.tracer.cfg
    for k in ("dE_J", "dy_pole_m", "V_star_m3", "p_star_Pa"):
        assert res.metrics[k] == pytest.approx(ref.metrics[k], rel=1e-6), k
    held = retried = 0
    for (pt, ds, new, theta), (nxt_pt, nxt_ds, _, _) in zip(tried[:-1], tried[1:]):
        if new is not None and nxt_pt is new and theta:
            bound = ds * (aim / theta) ** (1 / 3)
            assert nxt_ds <= bound * (1 + 1e-12)
            held += nxt_ds == pytest.approx(bound, rel=1e-12)
        if new is None and nxt_pt is pt and theta is not None and theta > cfg.theta_max:
            assert nxt_ds == pytest.approx(ds * min(0.8, max(0.25, (aim / theta) ** (1 / 3))), rel=1e-12)
            retried += 1
    assert held >= 1 and retried >= 1  # design A: both rules act
