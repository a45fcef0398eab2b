"""The mesh-sensitivity re-solve of suspicious snaps in ``solve_design`` (issue 5, item 3)."""
from __future__ import annotations

import pytest

import snapjump_cli.fe.solve as solve
from snapjump_cli.geometry.designs import get_design
from snapjump_cli.settings import MeshSettings, SolverSettings


def _fake(results_by_nt):
    def fake_solve_scene(scene, mesh, solver, **kw):
        r = results_by_nt[mesh.nt]
        if isinstance(r, Exception):
            raise r
        return solve.SceneResult(metrics=dict(r))
    return fake_solve_scene


def _m(dE, dy, method="path", snaps=True):
    return {"snaps": snaps, "dE_J": dE, "dE_norm": dE / (0.35e6 * 0.03**3), "dy_pole_m": dy, "lower_state_method": method}


def test_sound_snap_is_not_resolved(monkeypatch):
    monkeypatch.setattr(solve, "solve_scene", _fake({2: _m(0.03, 0.019), 3: RuntimeError("must not run")}))
    m = solve.solve_design(get_design("C"), MeshSettings(nt=2), SolverSettings())
    assert m["mesh_sensitive"] is False and m["dE_J_coarse"] is None and m["mesh_check"] == ""


@pytest.mark.parametrize("coarse,fine,sensitive", [
    (_m(1e-5, -0.001), _m(1.2e-5, -0.0011), True),     # pole moves up, dE moves 20 %
    (_m(0.03, 0.019, "descent"), _m(0.0301, 0.019), False),  # descent, confirmed by refinement
    (_m(1e-5, 0.001), _m(0.0, 0.0, snaps=False), True),    # tiny snap vanishes under refinement
])
def test_suspicious_snap_is_resolved_and_flagged(monkeypatch, coarse, fine, sensitive):
    monkeypatch.setattr(solve, "solve_scene", _fake({2: coarse, 3: fine}))
    m = solve.solve_design(get_design("C"), MeshSettings(nt=2), SolverSettings())
    assert m["mesh_sensitive"] is sensitive
    assert m["dE_J_coarse"] == coarse["dE_J"] and m["dy_pole_m_coarse"] == coarse["dy_pole_m"]
    assert m["dE_J"] == fine["dE_J"] and "re-solved at nt=3" in m["mesh_check"]


def test_refined_failure_keeps_coarse_and_flags(monkeypatch):
    monkeypatch.setattr(solve, "solve_scene", _fake({2: _m(1e-5, -0.001), 3: solve.SolveFailed("boom")}))
    m = solve.solve_design(get_design("C"), MeshSettings(nt=2), SolverSettings())
    assert m["mesh_sensitive"] is True and m["dE_J"] == 1e-5 and "boom" in m["mesh_check"]


def _cusp(m):
    return {**m, "fold_note": "volume limit at a near-cusp: ..."}


@pytest.mark.parametrize("fine,sensitive,still_cusp", [
    (_m(6.4e-3, 0.0124, "descent"), True, False),       # the fold is gone: dE moves 2.3x (design A)
    (_cusp(_m(2.6e-3, 0.0101)), True, True),             # same values, still a near-cusp
])
def test_near_cusp_is_resolved_finer_along_the_arc(monkeypatch, fine, sensitive, still_cusp):
    seen = []

    def fake(scene, mesh, solver, **kw):
        seen.append(mesh)
        return solve.SceneResult(metrics=dict(_cusp(_m(2.5e-3, 0.0100)) if mesh.nt == 2 else fine))

    monkeypatch.setattr(solve, "solve_scene", fake)
    m = solve.solve_design(get_design("A"), MeshSettings(nt=2, aspect=3.0), SolverSettings())
    # one more element through the thickness and elements half as long along the arc:
    # length ~ aspect t / nt goes 1.5 t -> 0.75 t
    assert [(s.nt, s.aspect) for s in seen] == [(2, 3.0), (3, 2.25)]
    assert m["mesh_sensitive"] is sensitive and m["dE_J"] == fine["dE_J"] and m["dE_J_coarse"] == 2.5e-3
    assert m["mesh_check"].startswith("volume limit at a near-cusp; re-solved at nt=3, aspect=2.25")
    assert ("still a near-cusp" in m["mesh_check"]) is still_cusp


class _Check:
    """A stand-in for the harmonic check's result."""

    def __init__(self, asym_first: bool):
        self.asym_first, self.asym_n = asym_first, 2 if asym_first else None

    def as_row(self) -> dict:
        return {"asym_first": self.asym_first, "asym_n": self.asym_n}


def _checked(monkeypatch, coarse, fine, asym_first: bool):
    """solve_scene, the harmonic check and the followed branch faked: returns the lists of the
    meshes solved, the results checked and the results followed."""
    import snapjump_cli.fe.branch.followed as followed
    import snapjump_cli.fe.stability.harmonics as harmonics

    seen, checked, follow = [], [], []

    def fake(scene, mesh, solver, **kw):
        seen.append(mesh.nt)
        return solve.SceneResult(metrics=dict(coarse if mesh.nt == 2 else fine), model=object(), path=object())

    def check(res, n):
        checked.append(res)
        return _Check(asym_first)
    monkeypatch.setattr(solve, "solve_scene", fake)
    monkeypatch.setattr(harmonics, "check_harmonics", check)
    monkeypatch.setattr(followed, "apply_followed", lambda res, h, N=0, mode="actuator": follow.append(res))
    return seen, checked, follow


def test_a_followed_solve_does_not_recheck_a_snap_its_actuator_does_not_make(monkeypatch):
    """With the followed branch on, a suspicious snap (here its lower state by descent) of a design
    that goes asymmetric first is not re-solved on the finer mesh: the harmonic check runs on the
    sweep's mesh first, once, and the branch is followed there; ``mesh_check`` says why."""
    seen, checked, follow = _checked(monkeypatch, _m(0.03, 0.019, "descent"), _m(0.0301, 0.019), True)
    res = solve.solve_checked(get_design("C"), MeshSettings(nt=2), SolverSettings(harmonics=4, follow=True))
    m = res.metrics
    assert seen == [2] and checked == [res] and follow == [res]
    assert m["dE_J"] == 0.03 and m["mesh_sensitive"] is False and m["dE_J_coarse"] is None
    assert m["mesh_check"] == ("lower state by descent; not re-checked: harmonic 2 goes unstable first "
                               "(the actuator does not make this snap)")
    assert m["asym_first"] is True and m["asym_n"] == 2


@pytest.mark.parametrize("follow,asym_first", [(True, False), (False, True), (False, False)])
def test_otherwise_the_suspicious_snap_is_rechecked_and_the_finer_solve_checked(monkeypatch, follow, asym_first):
    """A design that stays axisymmetric in a followed solve (its axisymmetric snap is the answer),
    and every design without the followed branch, is re-solved as before; the harmonic check and
    the branch are those of the finer solve."""
    seen, checked, followed = _checked(monkeypatch, _m(0.03, 0.019, "descent"), _m(0.0301, 0.019), asym_first)
    res = solve.solve_checked(get_design("C"), MeshSettings(nt=2), SolverSettings(harmonics=4, follow=follow))
    m = res.metrics
    assert seen == [2, 3] and checked[-1] is res and len(checked) == (2 if follow else 1)
    assert followed == ([res] if follow else [])
    assert m["dE_J"] == 0.0301 and m["dE_J_coarse"] == 0.03 and m["mesh_check"] == "lower state by descent; re-solved at nt=3"
