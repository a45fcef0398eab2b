"""The cavity kernel of the multi-harmonic model (its gradient and Hessian formed from phi-moments)
against the kernel it replaced (``tests/unit/mh_cavity_reference.py``: every phi point's dense
``L^T d2v L``) on random non-axisymmetric states, Q4 and Q9, several harmonic sets; the
derivatives themselves are checked against finite differences in ``test_multiharmonic.py``."""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_cli.fe.branch.model import MultiHarmonicModel
from tests.unit.test_harmonics_fd import _model, _state
from tests.unit.test_multiharmonic import _smooth_modes


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("hn", [[0], [0, 1, 2], [0, 2, 4, 6], [0, 1, 2, 3, 4]])
def test_phi_moment_cavity_equals_the_reference(order, hn):
    from snapjump_kernels.mh_cavity import mh_cavity
    from tests.unit.mh_cavity_reference import mh_cavity_reference

    M = _model(order)
    mh = MultiHarmonicModel(M, hn)
    rng = np.random.default_rng(3 + order + len(hn))
    U = mh.embed(_state(M, 4), _smooth_modes(M, hn, 0.03)) + 1e-3 * rng.standard_normal(mh.n)
    A = np.ascontiguousarray(mh.total_amplitudes(U))
    for want in (0, 1, 2):
        V, ge, He = mh_cavity(M.X, A, M.edges, mh.hn, mh.phis, mh.wphi, want)
        V0, ge0, He0 = mh_cavity_reference(M.X, A, M.edges, mh.hn, mh.phis, mh.wphi, want)
        assert V == pytest.approx(V0, rel=1e-14)
        assert ge.shape == ge0.shape and He.shape == He0.shape
        if want >= 1:
            np.testing.assert_allclose(ge, ge0, rtol=0, atol=1e-13 * np.abs(ge0).max())
        if want >= 2:
            np.testing.assert_allclose(He, He0, rtol=0, atol=1e-13 * np.abs(He0).max())
            if len(hn) > 1:  # the harmonics couple at this state: the cross blocks are compared
                nc = mh.nc
                assert np.abs(He0[:, 0, nc - 1]).max() > 1e-10 * np.abs(He0).max()
