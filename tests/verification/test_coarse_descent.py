"""The descent started in a coarser model (snapjump_cli.fe.branch.coarse).

The stratified sample's row 0 on a coarse mesh (Q9, nt 1, aspect 8): from its ``n = 1``
bifurcation, in a model with every harmonic 0..5, the energy descent at the bifurcation's volume
started with harmonics 0..4 comes to rest on the (asymmetric) state the model's own descent
reaches, a stable equilibrium of the model, in fewer iterations of that model. A landing that has
lost the harmonics breaking the upper state's symmetry is not taken (the guard).
"""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_cli.fe.axisym.lower_state import constrained_instability, descend_at_volume
from snapjump_cli.fe.branch.bifurcation import harmonic1_gauge, locate_bifurcation
from snapjump_cli.fe.branch.coarse import coarse_models, descend_coarse_to_fine
from snapjump_cli.fe.branch.model import MultiHarmonicModel, transfer
from snapjump_cli.fe.continuation import PathPoint, Tracer
from snapjump_cli.fe.solve import solve_scene
from snapjump_cli.geometry.caps import Design
from snapjump_cli.settings import MeshSettings, SolverSettings


@pytest.fixture(scope="module")
def upper():
    from dataclasses import replace

    res = solve_scene(Design(5.0, 80.0, 10.0, 86.0, 1.0), MeshSettings(order=2, nt=1, aspect=8.0),
                      SolverSettings(harmonics=4))
    bif = locate_bifurcation(res, 1)
    base = res.model
    mh = MultiHarmonicModel(base, list(range(6)), gauge=harmonic1_gauge(base, 1, bif.u))
    tr = Tracer(mh, replace(res.tracer.cfg, fused=False, mixed_tangent=False))
    U = mh.embed(bif.u)
    Phi = mh.embed(np.zeros(base.n), {1: bif.mode})
    z = tr.zeta(U, bif.p)[0]
    return tr, PathPoint(U, bif.p, z, np.zeros(len(z)), Phi / (tr.alpha * np.linalg.norm(Phi)), 0.0, 0.0)


def test_the_coarse_models_keep_the_body_and_gauge(upper):
    tr, up = upper
    mh = tr.pb
    (small,) = coarse_models(mh)
    assert list(small.hn) == [0, 1, 2, 3, 4] and small.gauge == mh.gauge and small.free_body == mh.free_body
    assert coarse_models(small) == []  # (0..4 itself has none)
    back = transfer(small, mh, transfer(mh, small, up.u, strict=False))
    assert np.array_equal(transfer(mh, small, back, strict=False), transfer(mh, small, up.u, strict=False))
    with pytest.raises(ValueError):
        transfer(mh, small, up.u)  # harmonic 5 is not kept: only a restriction drops them


def test_a_landing_back_in_the_upper_states_symmetry_is_not_taken(upper):
    from snapjump_cli.fe.branch.coarse import _breaks_symmetry

    tr, up = upper
    mh = tr.pb
    asym = up.u + 1e-2 * up.du_ds / np.linalg.norm(up.du_ds)  # harmonic 1 switched on
    assert _breaks_symmetry(mh, up.u, asym)
    assert not _breaks_symmetry(mh, up.u, 1.01 * up.u)  # axisymmetric, as the upper state
    full = np.random.default_rng(0).standard_normal(mh.n)  # an upper state that lacks no harmonic:
    assert _breaks_symmetry(mh, full, 1.01 * up.u)  # no condition


def test_the_coarse_start_lands_where_the_models_own_descent_does(upper):
    tr, up = upper
    mh = tr.pb
    n0 = mh.n_assemblies
    ref, msg_ref = descend_at_volume(tr, up)
    n_ref = mh.n_assemblies - n0
    n0 = mh.n_assemblies
    low, msg = descend_coarse_to_fine(tr, up)
    n_new = mh.n_assemblies - n0
    assert ref is not None and low is not None, (msg_ref, msg)
    assert "started from the descents with harmonics 0-4" in msg
    assert np.linalg.norm(low.u - ref.u) <= 1e-8 * np.linalg.norm(ref.u)
    dE_ref, dE = mh.energy(up.u) - mh.energy(ref.u), mh.energy(up.u) - mh.energy(low.u)
    assert dE == pytest.approx(dE_ref, rel=1e-10) and dE > 0.0
    assert low.zeta[0] == pytest.approx(up.zeta[0], rel=1e-9)
    assert constrained_instability(tr, mh.linearize(low.u, low.p)) == 0
    assert n_new < n_ref, (n_new, n_ref)  # the model's own iterations: fewer from the coarse state


@pytest.mark.parametrize("own", [False, True])
def test_a_coarse_descent_that_runs_out_of_iterations_is_not_walked_again_in_the_model(upper, monkeypatch, own):
    """Where the descent with harmonics 0..4 stops unconverged, the model's own descent from the same
    start (the same walk, dearer an iteration) is made only with ``OWN_AFTER_UNCONVERGED``; without it
    nothing is found and the message says why (the callers then trace the branch). The descents are
    stand-ins here: which model each ran in is what is checked."""
    import snapjump_cli.fe.branch.coarse as coarse
    from snapjump_cli.fe.axisym.descent import UNCONVERGED

    tr, up = upper
    ran = []

    def fake(tracer, upper_pt, start=None, **kw):
        ran.append(len(tracer.pb.hn))
        if len(tracer.pb.hn) < len(tr.pb.hn):
            return None, f"{UNCONVERGED} in 2000 iterations"
        return up, "descent converged in 3 iterations"

    monkeypatch.setattr(coarse, "descend_at_volume", fake)
    monkeypatch.setattr(coarse, "OWN_AFTER_UNCONVERGED", own)
    low, msg = descend_coarse_to_fine(tr, up)
    if own:
        assert ran == [5, 6] and low is up
    else:
        assert ran == [5] and low is None and msg == f"with harmonics 0-4: {UNCONVERGED} in 2000 iterations"
