"""A subcritical secondary branch landed by the sphere path before the probe of its first step
(snapjump_cli.fe.branch.trace.SPHERES_BEFORE_PROBE).

The actuator mode lands a subcritical secondary branch from its bifurcation at that volume; the
one-step probe that tells it subcritical is not needed where the sphere path's first state already
has a negative load (the energy falls from the bifurcation along the mode: a subcritical pitchfork)
and the path ends on a stable state that releases at least the micro-fold energy. Checked here:

* on a primary ``n = 1`` bifurcation of each kind (coarse meshes of two designs of the stratified
  sample), the sign of the sphere path's first load tells what the probe tells: the path with
  ``falling`` gives up at once at the supercritical one, and lands at the subcritical one;
* ``follow_strata`` row 8's design on a coarser mesh (Q9, nt 1, aspect 3: harmonic 2 first, its
  branch left at a secondary bifurcation into harmonic 1): the answer with the sphere path first
  is the probe-first answer bit for bit (the same state, the same values), without the probe's
  step and with fewer assemblies of the model with every harmonic.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import snapjump_cli.fe.branch.trace as trace
from snapjump_cli.fe.axisym.sphere_path import NOT_FALLING
from snapjump_cli.fe.branch.bifurcation import default_harmonics, locate_bifurcation
from snapjump_cli.fe.branch.followed import followed_metrics
from snapjump_cli.fe.branch.landing import sphere_landing
from snapjump_cli.fe.branch.trace import follow_branch
from snapjump_cli.fe.continuation import Tracer
from snapjump_cli.fe.solve import solve_scene
from snapjump_cli.fe.stability.harmonics import check_harmonics
from snapjump_cli.geometry.caps import Design
from snapjump_cli.settings import MeshSettings, SolverSettings

#: ``follow_strata`` rows 9 and 8 (bench/harmonics_sample/follow_strata.csv)
ROW9 = Design(7.4, 72.5, 25.0 / 3.0, 78.0, 1.0)
ROW8 = Design(8.0, 72.5, 15.0, 86.0, 1.0)


def _checked(design, aspect):
    res = solve_scene(design, MeshSettings(order=2, nt=1, aspect=aspect), SolverSettings(harmonics=4))
    chk = check_harmonics(res, 4)
    assert chk.asym_first
    return res, chk


@pytest.mark.parametrize("design, kind", [(ROW9, "supercritical"), (ROW8, "subcritical")])
def test_the_first_loads_sign_tells_the_probes_verdict(design, kind):
    res, _ = _checked(design, 8.0)
    bif = locate_bifurcation(res, 1)
    probe = follow_branch(res, bif, default_harmonics(1), max_steps=1)
    assert probe.first_kind == kind
    start, mh = probe.path.points[0], probe.model
    tracer = Tracer(mh, replace(probe.tracer.cfg, max_steps=res.tracer.cfg.max_steps))  # (not the probe's one step)
    low, msg = sphere_landing(tracer, start, falling=True)
    if kind == "supercritical":
        assert low is None and msg.startswith(NOT_FALLING), msg
    else:
        assert low is not None, msg
        assert mh.energy(low.u) < mh.energy(start.u)
        assert mh.volume(low.u) == pytest.approx(mh.volume(start.u), rel=1e-8)


@pytest.fixture(scope="module")
def both():
    res, chk = _checked(ROW8, 3.0)
    out = {}
    with pytest.MonkeyPatch.context() as mp:
        for flag in (True, False):
            mp.setattr(trace, "SPHERES_BEFORE_PROBE", flag)
            out[flag] = followed_metrics(res, chk, mode="actuator")
    return out


def test_the_secondary_branch_landed_before_the_probe_is_the_probe_firsts(both):
    first, probed = both[True], both[False]
    assert first.values["follow_sec_n"] == probed.values["follow_sec_n"] == 1
    fa, fb = first.branch, probed.branch
    assert fa.kind == fb.kind == "subcritical" and fa.lower_solver == fb.lower_solver
    assert fa.lower_note.startswith("sphere path: stable state") and fa.lower_note == fb.lower_note
    assert np.array_equal(fa.states.lower.u, fb.states.lower.u) and fa.states.lower.p == fb.states.lower.p
    for k in ("dE_J", "dy_pole_m", "V_star_m3", "p_star_Pa", "follow_sec_V_m3"):
        assert first.values[k] == probed.values[k], k
    # the probe's step is not made: the branch is its bifurcation alone, in fewer assemblies
    assert len(fa.path.points) == 1 and len(fb.path.points) == 2
    assert fa.model.n_assemblies < fb.model.n_assemblies
