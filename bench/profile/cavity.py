"""The multi-harmonic cavity kernel timed on a design's model (docs/harmonics.md, section 10.1).

    .venv/bin/python -m bench.profile.cavity --sample bench/harmonics_sample/follow_strata_n2.yaml --row 0 --N 8

builds the model with harmonics ``0..N`` on the design's mesh, at its axisymmetric upper state with
every harmonic perturbed (a fixed random state), and prints the CPU of one evaluation of
:func:`snapjump_kernels.mh_cavity.mh_cavity` for each ``want`` (0 the volume, 1 and its gradient,
2 and its Hessian; the median of ``--reps`` calls after one that compiles), with the model's
cavity edges, phi points and dofs. Run it at another commit for the figure before a change.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np


def time_cavity(sample: Path, row: int, N: int, reps: int) -> dict:
    """Median CPU-s of one cavity evaluation per ``want`` on design ``row`` of ``sample``."""
    from bench.profile.follow import scenes
    from snapjump_cli.fe.branch.model import MultiHarmonicModel
    from snapjump_cli.fe.solve import solve_scene
    from snapjump_kernels.mh_cavity import mh_cavity

    (_, scene, mesh, solver), = scenes([], sample, [row])
    res = solve_scene(scene, mesh, solver)
    mh = MultiHarmonicModel(res.model, list(range(N + 1)))
    u = mh.embed(res.states.upper.u) + 1e-4 * np.random.default_rng(1).standard_normal(mh.n)
    A = np.ascontiguousarray(mh.total_amplitudes(u))
    M = mh.base
    out = {"edges": int(M.edges.shape[0]), "phi points": int(mh.phis.shape[0]), "dofs": int(mh.n)}
    for want in (0, 1, 2):
        mh_cavity(M.X, A, M.edges, mh.hn, mh.phis, mh.wphi, want)
        ts = []
        for _ in range(reps):
            t0 = time.process_time()
            mh_cavity(M.X, A, M.edges, mh.hn, mh.phis, mh.wphi, want)
            ts.append(time.process_time() - t0)
        out[f"want {want}"] = float(np.median(ts))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.profile.cavity", description=__doc__.split("\n\n")[0])
    ap.add_argument("--sample", type=Path, default=Path("bench/harmonics_sample/follow_strata_n2.yaml"),
                    help="a sweep config whose design list holds the design")
    ap.add_argument("--row", type=int, default=0, help="the design's row in the sample")
    ap.add_argument("--N", type=int, default=8, help="the highest harmonic kept (0..N)")
    ap.add_argument("--reps", type=int, default=21, help="timed calls per want")
    a = ap.parse_args(argv)
    r = time_cavity(a.sample, a.row, a.N, a.reps)
    print(f"{a.sample.stem}#{a.row}, harmonics 0..{a.N}: {r['edges']} cavity edges, {r['phi points']} phi points, "
          f"{r['dofs']} dofs")
    for want in (0, 1, 2):
        print(f"  want {want}: {1e3 * r[f'want {want}']:.2f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
