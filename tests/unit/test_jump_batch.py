"""Many jump simulations at once (snapjump_cli.jump.batch, jump.jump_heights) give exactly the
results of one at a time."""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_cli.jump import JumpParams, jump_height, jump_heights, jump_trajectory
from snapjump_cli.jump.batch import sample_flights

RHO = 1000.0
C = (31.4e-3, 20.89e-3, RHO * 1.1224e-5, RHO * 9.170e-6)    # dE, dy, m_i, m_o
D = (0.324, 31.7e-3, RHO * 2.42e-5, RHO * 1.72e-5)
A_LIKE = (0.875e-3, 7.68e-3, C[2], C[3])
OVER = (1e-3, 5e-3, 2e-4, 1e-4)  # over-damped


def _designs() -> list[tuple]:
    """Under-, over- and critically damped designs from several heights, a few that do not snap,
    a bad input, and a random spread around design C."""
    k = 0.4**2 * 3e-4 / (4.0 * 2e-4 * 1e-4)
    crit = (0.5 * k * 5e-3**2, 5e-3, 2e-4, 1e-4)
    out = [(dE, dy, h, mi, mo) for dE, dy, mi, mo in (C, D, A_LIKE, OVER, crit)
           for h in (0.0, 1e-3, 1e-2)]
    out += [(0.0, C[1], 1e-3, C[2], C[3]), (C[0], -1e-3, 0.0, C[2], C[3]),  # no snap
            (C[0], C[1], -1.0, C[2], C[3]),                                  # bad input
            (C[0], C[1], float("nan"), C[2], C[3])]
    rng = np.random.default_rng(7)
    for _ in range(40):
        f = rng.uniform(0.3, 3.0, 4)
        out.append((C[0] * f[0], C[1] * f[1], rng.uniform(0.0, 0.03), C[2] * f[2], C[3] * f[3]))
    return out


@pytest.mark.parametrize("p", [JumpParams(), JumpParams(alpha=0.0), JumpParams(c_d=2.0),
                               JumpParams(c_d=0.0, alpha=1.0, t_max=0.05, max_contacts=20)],
                         ids=["default", "plastic", "heavy damping", "no dissipation"])
def test_many_at_once_equal_one_at_a_time(p):
    designs = _designs()
    together = jump_heights(designs, p)
    assert len(together) == len(designs)
    for d, r in zip(designs, together):
        try:
            alone = jump_height(*d, p)
        except ValueError as e:
            assert type(r) is ValueError and str(r) == str(e), d
            continue
        assert r == alone, d  # every field, floats to the bit


def test_a_few_at_a_time_equal_all_at_once():
    """run_many with fewer simulations running than designs (the next starting as one ends)."""
    from snapjump_cli.jump.trajectory import _simulate
    from snapjump_cli.jump.batch import run_many

    designs = _designs()
    p = JumpParams()
    want = jump_heights(designs, p)
    for width in (1, 3, 1000):
        got = [r if isinstance(r, Exception) else r.result
               for r in run_many((_simulate(*d, p) for d in designs), width)]
        assert len(got) == len(want)
        for g, w in zip(got, want):
            assert (type(g) is type(w) and str(g) == str(w)) if isinstance(w, Exception) else g == w


def test_sampled_flights_equal_the_flight_to_the_bit():
    """sample_flights answers requests of several designs, lengths and damping in blocks: the
    very numbers of PhaseModel.flight."""
    rng = np.random.default_rng(11)
    requests = []
    for dE, dy, mi, mo in (C, D, OVER):
        traj = jump_trajectory(dE, dy, 2e-3, mi, mo)
        md = traj._model
        for ph in traj._phases:
            if ph.kind == "flight":
                for n in (1, 2, 17, 300, 2500):
                    t = np.sort(rng.uniform(0.0, 200.0 * md.rel.dt, n))
                    requests.append((md.flight_at(ph), t))
    order = rng.permutation(len(requests))
    requests = [requests[i] for i in order]
    answers = sample_flights(requests)
    for (at, t), (y, v) in zip(requests, answers):
        Y, V, _, _ = at.md.flight(at.ph, t)
        assert np.array_equal(y, Y) and np.array_equal(v, V)
