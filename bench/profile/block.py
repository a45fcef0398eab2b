"""The stability count outside a branch, the whole tangent against its diagonal block
(docs/harmonics.md, section 10.7; docs/performance.md).

    .venv/bin/python -m bench.profile.block --sample bench/harmonics_sample/follow_strata_n2.yaml --row 5

traces the design's ``n_c`` branch (``--n``: another harmonic's) for a few steps (its model: the multiples of ``n_c``), lifts
its last state into :func:`snapjump_cli.fe.branch.secondary.full_model` (every harmonic ``0..4 n_c``)
and prints the CPU (the least of ``--reps`` after one call that compiles) of

* the count in the full model: its linearisation (the whole tangent) and the bordered ``LDL^T``'s
  constrained inertia (:func:`~snapjump_cli.fe.branch.secondary.unstable_modes`);
* the count outside the branch from the block of the other harmonics alone
  (:func:`~snapjump_cli.fe.branch.secondary.outside_modes`), with the branch's own count
  (:func:`~snapjump_cli.fe.branch.secondary.unstable_modes` of the branch model) beside it;
* the smallest eigenvalue outside the branch (:func:`~snapjump_cli.fe.stability.eigen.extra_eigen`:
  the block's band, its ``LDL^T`` for the inertia and the shift-invert), and the same as it was
  computed before (the whole tangent turned into CSR and sliced, scipy's sparse LU).

and checks that the counts agree.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np


def _least(f, reps: int) -> tuple[float, object]:
    out = f()
    best = np.inf
    for _ in range(reps):
        t0 = time.process_time()
        out = f()
        best = min(best, time.process_time() - t0)
    return best, out


def _sliced_eigen(full, u, p, dofs):
    """The smallest eigenvalue of the whole tangent's block as it was computed before the block
    was formed alone: the whole tangent turned into CSR and sliced, its inertia from the slice,
    shift-invert Lanczos with scipy's sparse LU."""
    import scipy.sparse.linalg as spla

    from snapjump_cli.fe.stability.eigen import lowest_eigen_below, negative_eigenvalues

    K = full.linearize(u, p).stiffness().tocsr()[dofs][:, dofs].tocsc()
    K.sum_duplicates()
    n_neg = negative_eigenvalues(K)
    sigma = -1e-6 * float(np.median(np.abs(K.diagonal())))
    v0 = np.random.default_rng(0).standard_normal(K.shape[0])
    vals, vecs = spla.eigsh(K, k=min(3, K.shape[0] - 1), sigma=sigma, which="LM", v0=v0)
    if n_neg > 0 and not (n_neg <= len(vals) and int(np.sum(vals < 0.0)) >= n_neg):
        vals, vecs = lowest_eigen_below(K, float(np.abs(vals).max()), v0)
    return float(np.min(vals))


def time_block(sample: Path, row: int, reps: int, n: int | None = None) -> dict:
    from bench.profile.follow import scenes
    from snapjump_cli.fe.branch.bifurcation import default_harmonics, locate_bifurcation
    from snapjump_cli.fe.branch.secondary import (extra_dofs, extra_harmonics, full_model, lift, outside_modes,
                                                  unstable_modes)
    from snapjump_cli.fe.branch.trace import follow_branch
    from snapjump_cli.fe.solve import solve_scene
    from snapjump_cli.fe.stability.eigen import extra_eigen
    from snapjump_cli.fe.stability.harmonics import check_harmonics

    (_, scene, mesh, solver), = scenes([], sample, [row])
    res = solve_scene(scene, mesh, solver)
    n = int(check_harmonics(res, solver.harmonics).asym_n) if n is None else int(n)
    if n < 2:
        raise SystemExit(f"harmonic {n}: its branch keeps every harmonic 0..{4 * n}; nothing lies outside it "
                         "(--n 2 for the branch of harmonic 2)")
    fr = follow_branch(res, locate_bifurcation(res, n), default_harmonics(n, None), max_steps=4)
    mh, pt = fr.model, fr.path.points[-1]
    full = full_model(mh, None, fr.bif.u)
    U = lift(mh, full, pt.u)
    others = extra_harmonics(mh, full)
    t_full, n_full = _least(lambda: unstable_modes(full, U, pt.p), reps)
    t_own, n_own = _least(lambda: unstable_modes(mh, pt.u, pt.p), reps)
    t_block, n_out = _least(lambda: outside_modes(mh, full, pt.u, pt.p), reps)
    t_eig, e_new = _least(lambda: extra_eigen(full, U, pt.p, others)[0], reps)
    t_eig_old, e_old = _least(lambda: _sliced_eigen(full, U, pt.p, extra_dofs(mh, full)), reps)
    return {"n_c": n, "dofs": full.n, "block dofs": int(full.block_band(U, pt.p, others)[1].n),
            "half-bandwidth": full.kl, "block half-bandwidth": int(full.block_band(U, pt.p, others)[1].kl),
            "count, full model (s)": t_full, "count, branch model (s)": t_own, "count outside, block (s)": t_block,
            "counts (full / own + outside)": f"{n_full} / {n_own} + {n_out}",
            "smallest outside, block (s)": t_eig, "smallest outside, whole tangent sliced (s)": t_eig_old,
            "smallest outside (block / sliced)": f"{e_new:.6g} / {e_old:.6g}"}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sample", type=Path, default=Path("bench/harmonics_sample/follow_strata_n2.yaml"))
    ap.add_argument("--row", type=int, default=5)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--n", type=int, default=None, help="the branch's harmonic (default: the harmonic check's first)")
    args = ap.parse_args(argv)
    for k, v in time_block(args.sample, args.row, args.reps, args.n).items():
        print(f"{k}: {v:.4f}" if isinstance(v, float) else f"{k}: {v}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
