"""Where a subcritical secondary branch lands (snapjump_cli.fe.branch.landing).

A paper-grid design (eta_i 7.4, theta_i 75, eta_o 5, theta_o 82, mu_i/mu_o 1; `follow_strata_n2`
row 22's, on a coarser mesh: Q9, nt 1, aspect 3): its `n = 2` branch loses stability to harmonic 1
and the branch leaving that secondary bifurcation lowers the volume at once (subcritical). The
actuator mode lands it from the bifurcation at its volume by the sphere path, before tracing more
of the branch; the slow reference, the energy descent from the bifurcation (started with
harmonics 0-4, then 0-8, the reference search's first start), reaches the same state.
"""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_cli.fe.branch.coarse import descend_coarse_to_fine
from snapjump_cli.fe.branch.followed import followed_metrics
from snapjump_cli.fe.branch.secondary import unstable_modes
from snapjump_cli.fe.solve import solve_scene
from snapjump_cli.fe.stability.harmonics import check_harmonics
from snapjump_cli.geometry.caps import Design
from snapjump_cli.settings import MeshSettings, SolverSettings


@pytest.fixture(scope="module")
def landed():
    res = solve_scene(Design(7.4, 75.0, 5.0, 82.0, 1.0), MeshSettings(order=2, nt=1, aspect=3.0),
                      SolverSettings(harmonics=4))
    chk = check_harmonics(res, 4)
    assert chk.asym_first and chk.asym_n == 2
    return followed_metrics(res, chk, mode="actuator")


def test_the_sphere_path_lands_the_subcritical_secondary_branch_where_the_descent_does(landed):
    out, fs = landed.values, landed.branch
    assert out["followed"] and fs.kind == "subcritical" and fs.parent is not None
    assert len(fs.path.points) == 1  # the secondary branch's bifurcation alone (landed before its first step)
    assert fs.lower_note.startswith("sphere path: stable state"), fs.lower_note
    up, low, full, tr = fs.states.upper, fs.states.lower, fs.model, fs.tracer
    assert full.volume(low.u) == pytest.approx(full.volume(up.u), rel=1e-8)
    assert unstable_modes(full, low.u, low.p) == 0
    assert full.energy(low.u) < full.energy(up.u)
    ref, msg = descend_coarse_to_fine(tr, up)
    assert ref is not None, msg
    assert np.linalg.norm(low.u - ref.u) < 1e-7 * np.linalg.norm(ref.u)
    assert full.energy(up.u) - full.energy(low.u) == pytest.approx(full.energy(up.u) - full.energy(ref.u), rel=1e-8)


def test_the_polish_with_the_mixed_newton_matrix_lands_on_the_same_state(landed, monkeypatch):
    """The zero of the sphere path's load is polished with the mixed Newton matrix (the element
    pressures interpolated along the step): the same state as the polish with the condensed
    tangent, to the Newton tolerance."""
    import snapjump_cli.fe.axisym.sphere_path as sp

    res = solve_scene(Design(7.4, 75.0, 5.0, 82.0, 1.0), MeshSettings(order=2, nt=1, aspect=3.0),
                      SolverSettings(harmonics=4))
    chk = check_harmonics(res, 4)
    monkeypatch.setattr(sp, "SPHERE_POLISH_MIXED", False)
    condensed = followed_metrics(res, chk, mode="actuator")
    a, b = landed.branch.states.lower.u, condensed.branch.states.lower.u
    assert condensed.branch.lower_note.startswith("sphere path: stable state")
    assert np.linalg.norm(a - b) < 1e-8 * np.linalg.norm(b)
    for key in ("dE_J", "dy_pole_m", "V_star_m3", "p_star_Pa"):
        assert landed.values[key] == pytest.approx(condensed.values[key], rel=1e-8)
