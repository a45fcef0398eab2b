"""Checks of a followed snap that lands on the axisymmetric inverted state (a fixture of the tests:
``from tests.landing import assert_axisymmetric_landing``)."""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_cli.fe.branch.secondary import lift, unstable_modes
from snapjump_cli.fe.branch.trace import MICRO_FOLD_DE

__all__ = ["asymmetric_first", "assert_axisymmetric_landing"]


def asymmetric_first(design, mesh, n: int):
    """The axisymmetric solve (harmonic check ``n <= 4``) of ``design`` on ``mesh`` and its check,
    which finds it asymmetric first in harmonic ``n``: ``(result, check)``."""
    from snapjump_cli.fe.solve import solve_scene
    from snapjump_cli.fe.stability.harmonics import check_harmonics
    from snapjump_cli.settings import SolverSettings

    res = solve_scene(design, mesh, SolverSettings(harmonics=4))
    chk = check_harmonics(res, 4)
    assert chk.asym_first and chk.asym_n == n
    return res, chk


def assert_axisymmetric_landing(answer, dE_axi: float, full=None) -> None:
    """The lower state of ``answer`` (a ``followed_metrics`` answer) is an equilibrium of its branch's
    model at the upper state's volume, stable under volume control there (and, with ``full``, in
    that model with every harmonic), axisymmetric, and below the upper state by more than the
    micro-fold energy (``dE_axi``: the axisymmetric snap's energy, J)."""
    fr = answer.branch
    mh, tr, up, lo = fr.model, fr.tracer, fr.states.upper, fr.states.lower
    lin = mh.linearize(lo.u, lo.p)
    assert float(np.linalg.norm(lin.R)) / tr.residual_scale(lin, tr.zeta(lo.u, lo.p)[1], lo.p) < 1e-6
    assert float(lo.zeta[0]) == pytest.approx(float(up.zeta[0]), rel=1e-9)  # at the snap's volume
    assert unstable_modes(mh, lo.u, lo.p) == 0
    assert full is None or unstable_modes(full, lift(mh, full, lo.u), lo.p) == 0
    A = np.abs(mh.amplitudes(lo.u))
    assert A[:, 2:].max() < 1e-9 * A[:, :2].max()  # axisymmetric
    assert answer.values["dE_J"] > MICRO_FOLD_DE * dE_axi
