"""Per-phase CPU profile of a followed branch (docs/harmonics.md, section 10.4; docs/performance.md).

    .venv/bin/python -m bench.follow_profile [SCENE] [--N N] [--repeat R] [--reference] [--json PATH]

``SCENE`` is one of :data:`bench.follow_study.SCENES` (default ``B``). The scene is solved
axisymmetrically, its bifurcation located, and its branch followed with the harmonics
``0, n_c, ..., N`` (default ``N = 4 n_c``, as the sweep does). Prints two markdown tables of CPU
seconds (``time.process_time``):

1. **one assembly** at the middle state of the followed path, each phase timed ``R`` times (the
   median): the element kernel's phases (:func:`snapjump_kernels.multiharmonic.mh_elements_phases`
   run up to each phase, the differences), the cavity, the scatter to the band, the band
   LDL^T, and the Python glue of :meth:`MultiHarmonicModel.linearize` (its time less the kernels'),
   with the flops of the tangent and the rate they run at;
2. **the whole followed solve**, every kernel call of the model timed where the model calls it
   (the element kernel with the tangent and without, the cavity, the scatters, the bordered
   factorisation and solves; the rest is the continuation's Python), with the steps, assemblies
   and dofs, and the axisymmetric solve's CPU time for the ratio.

``--reference`` runs both with the element kernel as it was before it was restructured
(:func:`snapjump_kernels.multiharmonic_reference.mh_elements_reference`), with the same answers bit
for bit: the before/after comparison, back to back on one machine.

``--compare`` instead follows the branch from one located bifurcation with the library kernel,
the reference kernel and the library kernel again, in this process (a bifurcation located in
another process differs at ~1e-9: ARPACK's start vector), and prints each run's answers
(``dE_J``, ``dy_pole_m``, ``V_star_m3``, ``p_star_Pa``), CPU seconds, steps and assemblies, and the
largest relative difference of the answers.
"""
from __future__ import annotations

import argparse
import json
import statistics
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

#: the element kernel's phases (``upto`` of :func:`mh_elements_phases`)
PHASES = ("pointwise material law (F, gent3, stored D)", "pressures, energy, residual",
          "phi-moments of D (per harmonic pair)", "B_k^T D_kl B_l blocks", "mirror + volumetric constraint")


def tangent_flops(ne: int, nen: int, nq: int, npr: int, K: int, nphi: int) -> dict[str, float]:
    """Flops (multiply and add counted apart) of the tangent phases of :func:`mh_elements` on
    ``ne`` elements, counting only the non-zeros of each node's B (a-column 4, b 3, c 4 of the
    9 rows): what the kernel computes, without its zero terms."""
    nc = 2 + 3 * (K - 1)
    nd = nen * nc
    ndk = [2] + [3] * (K - 1)
    nnz = [4, 3, 4]  # non-zeros of a node's B column per dof kind
    pairs = [(k, l) for k in range(K) for l in range(k, K)]
    moments = nq * (nphi * 81 + len(pairs) * nphi * 81) * 2
    db = nq * sum(nen * 9 * sum(nnz[:ndk[l]]) for _, l in pairs) * 2
    btdb = nq * sum(nen * nen * ndk[l] * sum(nnz[:ndk[k]]) for k, l in pairs) * 2
    gv = nphi * nq * nen * sum(sum(nnz[:n]) + n * npr for n in ndk) * 2
    vol = gv + nphi * (npr * npr * nd + npr * nd * (nd + 1) // 2) * 2
    return {"moments": ne * moments, "btdb": ne * (db + btdb), "volumetric": ne * vol}


def _median_cpu(fn, repeat: int) -> float:
    ts = []
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        ts.append(time.process_time() - t0)
    return statistics.median(ts)


def setup(name: str):
    """The scene's axisymmetric result (CPU seconds of its solve) and its bifurcation."""
    from bench.follow_study import solve_checked_scene
    from snapjump_cli.fe.follow import locate_bifurcation

    res, chk, t_axi = solve_checked_scene(name)
    if not chk["asym_first"]:
        raise SystemExit(f"{name} stays axisymmetric: nothing to follow")
    bif = locate_bifurcation(res, int(chk["asym_n"]))
    return res, bif, t_axi


@contextmanager
def instrumented(acc: dict, reference: bool = False):
    """Time (CPU) every kernel call the multi-harmonic model makes, into ``acc[name]``."""
    import snapjump_cli.fe.model as fmodel
    import snapjump_cli.fe.multiharmonic as fmh
    import snapjump_kernels.multiharmonic as kmh

    def wrap(name, fn, key=None):
        def w(*a, **kw):
            t0 = time.process_time()
            try:
                return fn(*a, **kw)
            finally:
                k = key(a) if key else name
                acc[k] = acc.get(k, 0.0) + time.process_time() - t0
                acc["n " + k] = acc.get("n " + k, 0) + 1
        return w

    saved = [(kmh, "mh_elements", kmh.mh_elements), (kmh, "mh_cavity", kmh.mh_cavity),
             (kmh, "scatter_vector", kmh.scatter_vector), (fmh, "scatter_band", fmh.scatter_band),
             (fmh, "factor_bordered", fmh.factor_bordered), (fmodel.BorderedSolver, "solve", fmodel.BorderedSolver.solve)]
    elements = kmh.mh_elements
    if reference:
        from snapjump_kernels.multiharmonic_reference import mh_elements_reference

        def elements(*a):
            return mh_elements_reference(*a, 5)
    kmh.mh_elements = wrap("", elements, key=lambda a: "elements, tangent" if a[15] >= 2 else
                           "elements, energy/residual")
    kmh.mh_cavity = wrap("cavity", kmh.mh_cavity)
    kmh.scatter_vector = wrap("scatter", kmh.scatter_vector)
    fmh.scatter_band = wrap("scatter", fmh.scatter_band)
    fmh.factor_bordered = wrap("bordered LDL^T", fmh.factor_bordered)
    fmodel.BorderedSolver.solve = wrap("bordered solves", fmodel.BorderedSolver.solve)
    try:
        yield acc
    finally:
        for obj, attr, fn in saved:
            setattr(obj, attr, fn)


def whole_solve(res, bif, hn, reference: bool = False) -> tuple[dict, object]:
    """The followed solve with every kernel call timed; returns the times and the result."""
    from snapjump_cli.fe.follow import follow_branch

    acc: dict = {}
    with instrumented(acc, reference):
        t0 = time.process_time()
        fr = follow_branch(res, bif, hn)
        acc["total"] = time.process_time() - t0
    return acc, fr


def one_assembly(mh, u: np.ndarray, p: float, repeat: int, reference: bool = False) -> dict[str, float]:
    """Median CPU seconds of each phase of one tangent assembly at ``(u, p)`` (the linearize and
    the glue are the library's, i.e. with the fast kernel, also with ``reference``)."""
    from snapjump_kernels.banded import band_ldlt
    from snapjump_kernels.calls import scatter_band
    from snapjump_kernels.multiharmonic import mh_cavity, mh_elements_phases, scatter_vector
    from snapjump_kernels.multiharmonic_reference import mh_elements_reference

    if reference:
        mh_elements_phases = mh_elements_reference  # noqa: F811 - the same signature

    M = mh.base
    A = np.ascontiguousarray(mh.total_amplitudes(u))

    def elements(upto: int, want: int = 2):
        return mh_elements_phases(A, M.conn, M.mat, M.mu, M.jm, M.kappa, M.dNdX, M.N_ref, M.Rq, M.Wq, M.Np, M.Minv,
                                  mh.hn, mh.phis, mh.wphi, want, mh.Fi, mh.Jimp, mh.Minvp, upto)

    def elements_lib():
        from snapjump_kernels.multiharmonic import mh_elements
        return mh_elements(A, M.conn, M.mat, M.mu, M.jm, M.kappa, M.dNdX, M.N_ref, M.Rq, M.Wq, M.Np, M.Minv, mh.hn,
                           mh.phis, mh.wphi, 2, mh.Fi, mh.Jimp, mh.Minvp)

    out: dict[str, float] = {}
    prev = 0.0
    for i, name in enumerate(PHASES):
        elements(i + 1)  # compile / warm
        t = _median_cpu(lambda: elements(i + 1), repeat)
        out["elements: " + name] = t - prev
        prev = t
    out["elements, all (want 2)"] = prev
    out["elements, residual only (want 1)"] = _median_cpu(lambda: elements(5, 1), repeat)
    _, _, re, Ke = elements(5)
    out["cavity (want 2)"] = _median_cpu(lambda: mh_cavity(M.X, A, M.edges, mh.hn, mh.phis, mh.wphi, 2), repeat)
    _, ge, He = mh_cavity(M.X, A, M.edges, mh.hn, mh.phis, mh.wphi, 2)

    def scatter():
        R = np.zeros(mh.n)
        scatter_vector(re, mh.edofs, mh.ecoef, 1.0, R)
        scatter_vector(ge, mh.gdofs, mh.gcoef, 1.0, R)
        ab = np.zeros((mh.n, mh.kl + 1))
        scatter_band(Ke, mh.edofs, mh.ecoef, 1.0, ab)
        scatter_band(He, mh.gdofs, mh.gcoef, -float(p), ab)
        return ab

    out["scatter to band"] = _median_cpu(scatter, repeat)
    ab = scatter()
    band_ldlt(ab.copy(), mh.band_ext)
    out["band LDL^T"] = _median_cpu(lambda: band_ldlt(ab.copy(), mh.band_ext), repeat)
    lin = mh.linearize(u, p)
    out["linearize (all of the above but LDL^T)"] = _median_cpu(lambda: mh.linearize(u, p), repeat)
    t_lib = _median_cpu(lambda: elements_lib(), repeat)
    out["Python glue of linearize"] = (out["linearize (all of the above but LDL^T)"] - t_lib
                                       - out["cavity (want 2)"] - out["scatter to band"])
    if reference:  # the linearize with the reference kernel
        out["linearize (all of the above but LDL^T)"] += out["elements, all (want 2)"] - t_lib
    assert lin is not None
    return out


def compare(res, bif, hn) -> float:
    """Follow the branch with the library kernel, the reference and the library again; print each
    run's answers and CPU; return the largest relative difference of the answers."""
    import snapjump_kernels.multiharmonic as kmh
    from snapjump_cli.fe.follow import follow_branch
    from snapjump_kernels.multiharmonic_reference import mh_elements_reference

    keys = ("dE_J", "dy_pole_m", "V_star_m3", "p_star_Pa")
    lib = kmh.mh_elements
    runs = {}
    try:
        for which in ("library", "reference", "library again"):
            kmh.mh_elements = (lambda *a: mh_elements_reference(*a, 5)) if which == "reference" else lib
            t0 = time.process_time()
            fr = follow_branch(res, bif, hn)
            row = {k: fr.metrics.get(k) for k in keys}
            row.update(cpu_s=time.process_time() - t0, steps=len(fr.path.points) - 1, assemblies=fr.model.n_assemblies)
            runs[which] = row
            print(which, json.dumps(row), flush=True)
    finally:
        kmh.mh_elements = lib
    diff = max(abs(runs[w][k] - runs["reference"][k]) / abs(runs["reference"][k])
               for w in ("library", "library again") for k in keys)
    print(f"largest relative difference of the answers, library against reference: {diff:.3g}")
    return diff


def envelope_flops(mh) -> float:
    """Flops of the band LDL^T on the model's envelope (``sum_j ext_j (ext_j + 3)``)."""
    e = np.asarray(mh.band_ext, float)
    return float(np.sum(e * (e + 3.0)))


def main(argv=None) -> int:
    from snapjump_cli.fe.follow import default_harmonics

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", nargs="?", default="B")
    ap.add_argument("--N", type=int, default=0, help="highest harmonic kept (default 4 n_c)")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--reference", action="store_true", help="with the element kernel before the restructuring")
    ap.add_argument("--compare", action="store_true",
                    help="the answers and CPU of the branch with the library and the reference kernel")
    ap.add_argument("--json", type=Path, default=None, help="also write the numbers here")
    a = ap.parse_args(argv)
    res, bif, t_axi = setup(a.scene)
    hn = default_harmonics(bif.n, a.N or None)
    if a.compare:
        print(f"axisymmetric solve {t_axi:.2f} CPU-s")
        compare(res, bif, hn)
        return 0
    acc, fr = whole_solve(res, bif, hn, a.reference)
    mh = fr.model
    pts = fr.path.points
    mid = pts[len(pts) // 2]
    one = one_assembly(mh, mid.u, mid.p, a.repeat, a.reference)
    M = mh.base
    ne, nen = M.conn.shape
    fl = tangent_flops(ne, nen, M.Wq.shape[1], M.Np.shape[1], len(hn), len(mh.phis))
    print(f"## {a.scene}{' (reference kernel)' if a.reference else ''}: harmonics {hn}, {mh.n} dofs, {ne} elements of {nen} nodes, {len(mh.phis)} phi points, "
          f"band kl {mh.kl}, mean envelope {np.mean(mh.band_ext):.1f}\n")
    print("| one assembly (middle of the path) | CPU ms | share | Gflop | GFlop/s |")
    print("|---|---|---|---|---|")
    total1 = one["linearize (all of the above but LDL^T)"] + one["band LDL^T"]
    gfl = {"elements: " + PHASES[2]: fl["moments"], "elements: " + PHASES[3]: fl["btdb"],
           "elements: " + PHASES[4]: fl["volumetric"], "band LDL^T": envelope_flops(mh)}
    for k, v in one.items():
        share = f"{100 * v / total1:.0f} %" if not k.startswith(("elements, all", "linearize", "elements, residual")) \
            else ""
        f = gfl.get(k)
        fs = f"{f / 1e9:.3f}" if f else ""
        rate = f"{f / 1e9 / v:.2f}" if f and v > 0 else ""
        print(f"| {k} | {1e3 * v:.2f} | {share} | {fs} | {rate} |")
    print(f"| one assembly + LDL^T | {1e3 * total1:.2f} | 100 % | | |")
    steps = len(pts) - 1
    print(f"\n| whole followed solve (N = {hn[-1]}) | CPU s | share | calls |")
    print("|---|---|---|---|")
    known = 0.0
    for k in ("elements, tangent", "elements, energy/residual", "cavity", "scatter", "bordered LDL^T",
              "bordered solves"):
        v = acc.get(k, 0.0)
        known += v
        print(f"| {k} | {v:.2f} | {100 * v / acc['total']:.0f} % | {acc.get('n ' + k, 0)} |")
    print(f"| continuation, Python and the rest | {acc['total'] - known:.2f} | "
          f"{100 * (acc['total'] - known) / acc['total']:.0f} % | |")
    print(f"| **total** | **{acc['total']:.2f}** | | {steps} steps, {mh.n_assemblies} assemblies |")
    print(f"\naxisymmetric solve {t_axi:.2f} CPU-s; followed / axisymmetric = {acc['total'] / t_axi:.1f}x; "
          f"dE_J {fr.metrics.get('dE_J')!r}, dy_pole_m {fr.metrics.get('dy_pole_m')!r}")
    if a.json:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        a.json.write_text(json.dumps({"scene": a.scene, "hn": hn, "ndof": mh.n, "one_assembly_s": one,
                                      "whole_solve_s": acc, "steps": steps, "assemblies": mh.n_assemblies,
                                      "cpu_axisym_s": t_axi, "flops": fl, "metrics": fr.metrics},
                                     indent=1, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
