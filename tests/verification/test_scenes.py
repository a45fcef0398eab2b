"""Snap metrics of the paper's scenes at the default mesh: built-in consistency checks
(docs/physics.md section 5), the comparisons with the paper that must hold, and regression values.

Regression values are the answers ``snapjump curve`` reports at the default settings (order 2,
nt 2, aspect 2; :func:`snapjump_cli.fe.solve.solve_checked`, i.e. after the mesh check) and are
listed in the scenes table of docs/verification.md beside the paper's values; a change of more than
0.3 % means the numerics changed and that table must be regenerated. Design A's default mesh folds
at a near-cusp (2.78 mJ, the coarse mesh's branch); the answer reported, and pinned here, is the
re-solve on the finer mesh (nt 3, aspect 1.5), which agrees with the mesh-converged 6.38-6.40 mJ.
"""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_cli.geometry.designs import FIG1_CAPS, fig1_caps, get_design
from snapjump_cli.geometry.caps import CapScene, Design
from snapjump_cli.fe.axisym.lower_state import constrained_instability, snap_at_fixed_volume
from snapjump_cli.fe.axisym.descent import descend_at_volume, descent_starts
from snapjump_cli.settings import MeshSettings, SolverSettings
from snapjump_cli.fe.solve import solve_checked, solve_scene, suspicious_snap

SCENES = {
    **fig1_caps(("cap30-clamped", "cap8.5-roller-point")),
    "A": get_design("A"),
    "B": get_design("B"),
    "C": get_design("C"),
    "D": get_design("D"),
}
# (dE [J], dy_pole [m]) reported at the default mesh
REGRESSION = {
    "cap30-clamped": (1.5441919e-04, 3.8406749e-03),
    "cap8.5-roller-point": (3.3818771e-03, 6.9140667e-03),
    "A": (6.38695e-03, 1.23670e-02),  # after the near-cusp re-solve (coarse fold: 2.7800e-3, 1.0213e-2)
    "B": (1.2460825e-02, 1.0216149e-02),
    "C": (2.9431153e-02, 1.8937141e-02),
    "D": (3.1089187e-01, 3.8934970e-02),
}
MU, R = 0.35e6, 0.030


@pytest.fixture(scope="module")
def results():
    return {name: solve_scene(sc, MeshSettings(), SolverSettings()) for name, sc in SCENES.items()}


@pytest.mark.parametrize("name", list(SCENES))
def test_dE_two_ways_agree(results, name):
    m = results[name].metrics
    assert m["snaps"] and m["lower_state_method"] == "path"
    assert m["dE_rel_diff"] <= 5e-3
    assert abs(m["dE_energy_J"] - m["dE_path_J"]) <= 5e-3 * m["dE_J"]


@pytest.mark.parametrize("name", list(SCENES))
def test_upper_is_a_volume_limit_and_lower_is_stable_at_the_same_volume(results, name):
    r = results[name]
    up, lo = r.states.upper, r.states.lower
    assert abs(up.tangent[0]) < 1e-6  # dV/ds = 0 located precisely, not read off a step
    assert lo.zeta[0] == pytest.approx(up.zeta[0], rel=1e-9)
    assert lo.tangent[0] > 0
    lin = r.model.linearize(lo.u, lo.p)
    assert constrained_instability(r.tracer, lin) == 0
    assert r.metrics["max_dilatation"] < 1e-3  # incompressible: |theta - 1| = |p_e| / kappa


@pytest.fixture(scope="module")
def reported(results):
    """The answers as the commands report them (solve_checked): A (near-cusp) and the thin clamped
    cap (a tiny snap, dE < 1e-4 mu R^3) are re-solved one level finer."""
    out = {}
    for name, r in results.items():
        if suspicious_snap(r.metrics):
            out[name] = solve_checked(SCENES[name], MeshSettings(), SolverSettings()).metrics
        else:
            out[name] = r.metrics
    return out


@pytest.mark.parametrize("name", list(SCENES))
def test_regression(reported, name):
    m = reported[name]
    assert bool(m.get("mesh_check")) is (name in ("A", "cap30-clamped"))
    assert bool(m.get("mesh_sensitive")) is (name == "A")  # the thin cap holds under refinement
    dE, dy = REGRESSION[name]
    assert m["dE_J"] == pytest.approx(dE, rel=3e-3)
    assert m["dy_pole_m"] == pytest.approx(dy, rel=3e-3)


def test_thin_clamped_cap_against_paper(results):
    m = results["cap30-clamped"].metrics
    paper_dE, paper_dy = FIG1_CAPS["cap30-clamped"][2]  # 1.50e-5, 0.131
    assert m["dE_J"] / (MU * R**3) == pytest.approx(paper_dE, rel=0.10)
    assert m["dy_pole_m"] / R == pytest.approx(paper_dy, rel=0.03)


def test_designs_C_and_D_against_paper(results):
    c, d = results["C"].metrics, results["D"].metrics
    assert c["dE_J"] == pytest.approx(31.4e-3, rel=0.10)
    assert c["dy_pole_m"] == pytest.approx(20.89e-3, rel=0.12)
    assert d["dE_J"] == pytest.approx(0.324, rel=0.06)
    # D's pole travel is ~23 % above the paper's (docs/physics.md section 7 reports ~20 % from an independent
    # solver); asserted as a regression above, documented in the README
    for m in (c, d):
        assert 0 < m["h_imp_m"] < m["L0_m"]


@pytest.mark.parametrize("start", ["upper", "post-snap"])
@pytest.mark.parametrize("name", ["C", "D"])
def test_descent_lands_on_the_path_lower_state(results, name, start):
    """The descent (the fallback when the path does not return to V*) reaches the state the
    path defines, both from the upper state along its unstable mode and from a post-snap point."""
    r = results[name]
    st = r.states
    starts = descent_starts(r.path.points[: st.k_return], st.upper, st.k_before)
    low, msg = descend_at_volume(r.tracer, st.upper, start=None if start == "upper" else starts[0])
    assert low is not None, msg
    E = r.model.energy
    assert E(low.u) == pytest.approx(E(st.lower.u), rel=1e-8)
    assert np.abs(low.u - st.lower.u).max() < 1e-6


@pytest.mark.parametrize("name", ["C", "D"])
def test_fixed_volume_path_lands_on_the_path_lower_state(results, name):
    """The continuation at fixed volume in the pole displacement (the lower state when the path
    does not return to V*) reaches the state the path defines, in tens of steps."""
    r = results[name]
    st = r.states
    low, msg = snap_at_fixed_volume(r.tracer, st.upper)
    assert low is not None, msg
    E = r.model.energy
    assert E(low.u) == pytest.approx(E(st.lower.u), rel=1e-8)
    assert np.abs(low.u - st.lower.u).max() < 1e-6
    assert int(msg.split(" in ")[1].split()[0]) < 100, msg  # steps


def test_thin_cap_mesh_convergence():
    vals = [solve_scene(SCENES["cap30-clamped"], MeshSettings(order=2, nt=nt, aspect=a), SolverSettings()).metrics["dE_J"]
            for nt, a in ((1, 4.0), (2, 2.0), (4, 1.0))]
    d1, d2 = abs(vals[1] - vals[0]), abs(vals[2] - vals[1])
    assert d2 < 0.5 * d1, vals
    assert d2 / vals[2] < 5e-3


def test_outer_cap_stored_energy_two_ways():
    """E_o at p/mu_o = 0.5 (state solved exactly there) equals the area under the traced p-V path."""
    r = solve_scene(CapScene(theta_deg=90, eta=16.5, kind="outer"), MeshSettings(), SolverSettings())
    m, c = r.metrics, r.curve
    assert not m["snaps"] and m["stop_reason"] == "pressure bound"
    p, V = c["p_Pa"], c["V_m3"]
    k = int(np.searchsorted(p, 0.5 * 0.35e6))  # p increases monotonically for this balloon-like cap
    assert np.all(np.diff(p[: k + 1]) > 0)
    w = (0.5 * 0.35e6 - p[k - 1]) / (p[k] - p[k - 1])
    V_end = V[k - 1] + w * (V[k] - V[k - 1])
    area = np.trapezoid(p[:k], V[:k]) + 0.5 * (p[k - 1] + 0.5 * 0.35e6) * (V_end - V[k - 1])
    assert m["E_o_J"] == pytest.approx(area, rel=1e-2)


def test_ballooning_outer_cap_snap_found_by_descent():
    """Grid design (5.6, 80, 20, 90, 5.8): the soft thin outer cap balloons (V* ~ 0.8 l); after
    the snap the path folds back to zero cavity volume and never returns to V*. The descent from
    the upper state must reach a stable state at V* (it crawled for >600 iterations with a fixed
    shift floor: the sweep's one failure class)."""
    from snapjump_cli.geometry.caps import Design

    r = solve_scene(Design(5.6, 80.0, 20.0, 90.0, 5.8), MeshSettings(order=2, nt=2, aspect=3.0), SolverSettings())
    m, st = r.metrics, r.states
    assert m["stop_reason"] == "cavity volume reached zero"
    assert m["lower_state_method"] == "descent"
    assert st.lower.zeta[0] == pytest.approx(st.upper.zeta[0], rel=1e-9)
    lin = r.model.linearize(st.lower.u, st.lower.p)
    assert constrained_instability(r.tracer, lin) == 0
    assert constrained_instability(r.tracer, r.model.linearize(st.upper.u, st.upper.p)) <= 1
    assert m["dE_J"] > 0.05 and m["dy_pole_m"] > 0.01
    # found by the fixed-volume path; the energy descent reaches the same state
    assert m["lower_state_solver"] == "volume-path"
    low, msg = descend_at_volume(r.tracer, st.upper)
    assert low is not None, msg
    assert r.model.energy(low.u) == pytest.approx(r.model.energy(st.lower.u), rel=1e-9)
    assert np.abs(low.u - st.lower.u).max() < 1e-6
    # the outer cap is past its ballooning pressure maximum: when the inner cap inverts it gives up
    # volume and its pressure rises, so p_lower may exceed p* here (it does: 6102 vs 6079 Pa)
    assert np.isfinite(m["p_lower_Pa"]) and m["p_lower_Pa"] > 0


def test_thin_inner_cap_on_soft_outer_cap_descends_monotonically():
    """Extended-domain design (11.5146, 71.8373, 25.9177, 77.5991, 6.1632): a thin inner cap whose
    snap releases ~2/3 of the stored energy; the path folds back to zero cavity volume. The descent
    once accepted overshooting steps unchecked and climbed to 5x the energy; it must now reach a
    stable state at V* with the energy falling all the way (the same state on nt = 2 and 3:
    dE 49.7 / 49.8 mJ)."""
    from snapjump_cli.geometry.caps import Design

    r = solve_scene(Design(11.5146, 71.8373, 25.9177, 77.5991, 6.1632), MeshSettings(), SolverSettings())
    m, st = r.metrics, r.states
    assert m["lower_state_method"] == "descent"
    assert st.lower.zeta[0] == pytest.approx(st.upper.zeta[0], rel=1e-9)
    assert constrained_instability(r.tracer, r.model.linearize(st.lower.u, st.lower.p)) == 0
    assert m["dE_J"] == pytest.approx(0.0497, rel=0.02)


def test_design_A_coarse_fold_is_flagged_and_clean_folds_are_not(results):
    """On meshes coarse along the arc (elements >= t long) design A's volume limit is a near-cusp:
    K_T gains a second unstable mode within 1e-3 of (V*, p*) - in the fold's own step at the
    default aspect 2, 6e-7 after it at the sweep's aspect 3. On finer meshes the path goes past it
    (test below). Such a fold must be flagged - for the sweep a reason to re-solve - and the clean
    folds of the other scenes must not be (the thin cap's fold follows its pressure maximum within
    a step: K_T's first unstable mode is not a reason; B's next pressure extremum is 9 % lower)."""
    from snapjump_cli.fe.solve import suspicious_snap

    a = results["A"]
    k = a.states.k_before
    pts = a.path.points
    assert pts[k].n_neg == 1 and pts[k + 1].n_neg == 2  # the second mode appears in the fold's step
    assert "near-cusp" in a.metrics["fold_note"]
    assert suspicious_snap(a.metrics) == "volume limit at a near-cusp"
    a3 = solve_scene(SCENES["A"], MeshSettings(order=2, nt=2, aspect=3.0), SolverSettings()).metrics
    assert "near-cusp" in a3["fold_note"] and a3["p_star_Pa"] > 0.9 * a3["p_max_Pa"]
    for name in ("cap30-clamped", "cap8.5-roller-point", "B", "C", "D"):
        assert results[name].metrics["fold_note"] == "", name
    for name in ("B", "C", "D"):
        assert suspicious_snap(results[name].metrics) == "", name


def test_design_A_refined_along_the_arc_passes_the_coarse_fold():
    """Design A with elements half as long along the arcs (nt 2, aspect 1): no fold near p_max; the
    inner cap inverts stably under volume control and the first volume limit is at p* ~ 8 Pa. The
    snap there is the mesh-converged one (nt 2 / aspect 1, nt 3 / 2 and nt 4 / 2 give dE 6.382,
    6.396, 6.390 mJ and dy_pole 12.368, 12.367, 12.372 mm; README) - the default mesh's 2.78 mJ
    fold near p_max is the coarse mesh's branch."""
    m = solve_scene(SCENES["A"], MeshSettings(order=2, nt=2, aspect=1.0), SolverSettings()).metrics
    assert m["fold_note"] == ""
    assert m["p_star_Pa"] < 0.02 * m["p_max_Pa"]
    assert m["lower_state_method"] == "descent"
    assert m["dE_J"] == pytest.approx(6.390e-3, rel=0.01)
    assert m["dy_pole_m"] == pytest.approx(12.37e-3, rel=0.01)


def test_p_max_is_the_loading_peak_independent_of_the_steps(results):
    """p_max is the largest pressure on the loading path's Hermite curve: the default steps give it
    to the accuracy of a trace with ~5x more steps (3e-7 on C; the points alone miss it by 9e-5)."""
    import dataclasses

    fine = solve_scene(SCENES["C"], MeshSettings(), dataclasses.replace(SolverSettings(), ds_max=0.1, max_turn_deg=2.0))
    m, f = results["C"].metrics, fine.metrics
    assert len(fine.path.points) > 4 * len(results["C"].path.points)
    assert abs(m["p_max_Pa"] - f["p_max_Pa"]) <= 1e-5 * f["p_max_Pa"]
    assert m["p_star_Pa"] <= m["p_max_Pa"]


def test_a_finer_trace_gets_a_larger_post_snap_budget():
    """The post-snap path of the grid design (8, 80, 8.33, 82, 1) comes back to V* after ~150
    steps at the default steps and after ~1500 at 50x shorter ones: with the budget tied to
    ``max_steps`` (3/4 of it) the fine trace finds the same lower state on the path, not by the
    fixed-volume fallback (with a fixed 1500 it ran out just before V*)."""
    import dataclasses

    from snapjump_cli.fe.solve import post_snap_budget

    design = Design(eta_i=8, theta_i_deg=80, eta_o=25 / 3, theta_o_deg=82, mu_ratio=1)
    mesh = MeshSettings(order=2, nt=2, aspect=3.0)  # the paper grid's mesh
    coarse = solve_scene(design, mesh, SolverSettings())
    fine_solver = dataclasses.replace(SolverSettings(), ds0=0.02, ds_max=0.02, max_turn_deg=2.0, max_steps=20000)
    assert post_snap_budget(SolverSettings()) == 1500 and post_snap_budget(fine_solver) == 15000
    fine = solve_scene(design, mesh, fine_solver)
    st = fine.states
    assert len(fine.path.points) - 1 - st.k_before > 1500  # more than the old fixed budget
    for r in (coarse, fine):
        assert r.metrics["lower_state_method"] == "path"
    assert fine.metrics["dE_J"] == pytest.approx(coarse.metrics["dE_J"], rel=1e-9)
    assert fine.metrics["dy_pole_m"] == pytest.approx(coarse.metrics["dy_pole_m"], rel=1e-6)
