"""The multi-harmonic tangent assembly and its factorisation timed on a design's model
(docs/harmonics.md, section 10.4; docs/performance.md).

    .venv/bin/python -m bench.profile.assembly --sample bench/harmonics_sample/follow_strata_n2.yaml --row 5 --N 8

builds the model with harmonics ``0..N`` on the design's mesh (the phi rule ``--n-phi``, default the
model's own), at its axisymmetric upper state with every harmonic perturbed (a fixed random state),
and prints the CPU of one linearisation (:meth:`MultiHarmonicModel.linearize`: the fused element
pass :func:`snapjump_kernels.mh_element.mh_assemble_band` and the cavity) and of one bordered
``LDL^T`` of it, the least and the median of ``--reps`` calls after one that compiles. Run it at
another commit for the figure before a change.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np


def _times(f, reps: int) -> tuple[float, float]:
    f()
    ts = []
    for _ in range(reps):
        t0 = time.process_time()
        f()
        ts.append(time.process_time() - t0)
    return float(np.min(ts)), float(np.median(ts))


def time_assembly(sample: Path, row: int, N: int, reps: int, n_phi: int | None = None) -> dict:
    """Least and median CPU-s of one linearisation and one factorisation on design ``row`` of ``sample``."""
    from bench.profile.follow import scenes
    from snapjump_cli.fe.branch.model import MultiHarmonicModel
    from snapjump_cli.fe.solve import solve_scene

    (_, scene, mesh, solver), = scenes([], sample, [row])
    res = solve_scene(scene, mesh, solver)
    mh = MultiHarmonicModel(res.model, list(range(N + 1)), n_phi=n_phi)
    u = mh.embed(res.states.upper.u) + 1e-4 * np.random.default_rng(1).standard_normal(mh.n)
    p = float(res.states.upper.p)
    lin = mh.linearize(u, p)
    c_u = np.random.default_rng(2).standard_normal(mh.n)
    out = {"elements": int(mh.base.conn.shape[0]), "phi points": int(mh.phis.shape[0]), "dofs": int(mh.n),
           "kl": int(mh.kl)}
    out["linearize"] = _times(lambda: mh.linearize(u, p), reps)
    out["factor"] = _times(lambda: lin.factor(c_u, 0.0), reps)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.profile.assembly", description=__doc__.split("\n\n")[0])
    ap.add_argument("--sample", type=Path, default=Path("bench/harmonics_sample/follow_strata_n2.yaml"),
                    help="a sweep config whose design list holds the design")
    ap.add_argument("--row", type=int, default=5, help="the design's row in the sample")
    ap.add_argument("--N", type=int, default=8, help="the highest harmonic kept (0..N)")
    ap.add_argument("--n-phi", type=int, default=None, help="intervals of the phi rule (default the model's)")
    ap.add_argument("--reps", type=int, default=25, help="timed calls of each")
    a = ap.parse_args(argv)
    r = time_assembly(a.sample, a.row, a.N, a.reps, a.n_phi)
    print(f"{a.sample.stem}#{a.row}, harmonics 0..{a.N}: {r['elements']} elements, {r['phi points']} phi points, "
          f"{r['dofs']} dofs, half-band {r['kl']}")
    for k in ("linearize", "factor"):
        print(f"  {k}: least {1e3 * r[k][0]:.2f} ms, median {1e3 * r[k][1]:.2f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
