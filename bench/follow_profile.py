"""Per-phase CPU profile of a followed branch, before and after (docs/harmonics.md, section 10.4).

    .venv/bin/python -m bench.follow_profile [SCENE] [--N N] [--repeat R] [--before KERNEL.py]
                                             [--reference] [--compare [--rounds R]] [--json PATH]
    .venv/bin/python -m bench.follow_profile [SCENE] --step-grow G [G ...]

``SCENE`` is one of :data:`bench.follow_study.SCENES` (default ``B``). The scene is solved
axisymmetrically, its bifurcation located, and its branch followed with the harmonics
``0, n_c, ..., N`` (default ``N = 4 n_c``, as the sweep does), in two modes (:func:`mode`), in
this process, back to back: **after**, the library as it is, and **before**, the model's
assembly and factorisation of 2026-11-27 (element matrices in memory, ``scatter_band``, the band
and the factors in fresh arrays: ``MultiHarmonicModel.fused_assembly = False``) with the element
kernel of ``--before`` (a kernel source file, e.g. the main branch's ``kernels/multiharmonic.py``
before this change, imported from a copy under ``bench/out/``; default the library's own), or
with ``--reference`` the kernel before 2026-11-27
(:mod:`snapjump_kernels.multiharmonic_reference`). Every kernel is compiled before anything is
timed. Prints two markdown tables of CPU seconds (``time.process_time``), before and after:

1. **one assembly** at the middle state of the followed path, each phase timed ``R`` times (the
   median; the better of two alternated rounds): the element kernel's phases
   (:func:`snapjump_kernels.multiharmonic.mh_elements_phases` run up to each phase, the
   differences), the cavity, the scatter to the band (after: what the fused pass
   :func:`~snapjump_kernels.multiharmonic.mh_assemble_band` costs beyond the element kernel,
   plus the cavity's scatter), the bordered band LDL^T with ``K^-1 b``, and the Python glue of
   :meth:`MultiHarmonicModel.linearize` (its time less the kernels'), with the flops of the
   tangent and the LDL^T and the rates they run at;
2. **the whole followed solve**, every kernel call of the model timed where the model calls it
   (the element kernel with the tangent and without, the cavity, the scatters, the bordered
   factorisation and solves; the rest is the continuation's Python), with the steps and
   assemblies, the axisymmetric solve and check's CPU time (timed in between) and the
   followed/axisymmetric ratios, and whether the answers of both modes are identical.

``--compare`` instead follows the branch from one located bifurcation after, before and then the
axisymmetric solve and check, ``--rounds`` times (a bifurcation located in another process may
differ at ~1e-9), and prints each run's answers (``dE_J``, ``dy_pole_m``, ``V_star_m3``,
``p_star_Pa``), CPU seconds, steps and assemblies, the medians, the ratios and the largest
relative difference of the answers.

``--step-grow G ...`` follows the branch with the continuation's step growth set to each ``G`` in
turn (an experiment on the number of assemblies; the constant is not changed elsewhere).
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
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
    """The scene's axisymmetric result, its bifurcation, and the CPU seconds of its solve and
    check as the first call in this process (with the one-time costs: imports, loading the
    compiled kernels)."""
    from bench.follow_study import solve_checked_scene
    from snapjump_cli.fe.branch.bifurcation import locate_bifurcation

    t0 = time.process_time()
    res, chk, _ = solve_checked_scene(name)
    t_axi = time.process_time() - t0
    if not chk.asym_first:
        raise SystemExit(f"{name} stays axisymmetric: nothing to follow")
    bif = locate_bifurcation(res, int(chk.asym_n))
    return res, bif, t_axi


@contextmanager
def instrumented(acc: dict):
    """Time (CPU) every kernel call the multi-harmonic model makes, into ``acc[name]``."""
    import snapjump_cli.fe.axisym.model as fmodel
    import snapjump_cli.fe.branch.model as fmh
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

    import snapjump_kernels.multiharmonic_band as kmb

    saved = [(kmh, "mh_elements", kmh.mh_elements), (kmh, "mh_assemble_band", kmh.mh_assemble_band),
             (kmh, "mh_cavity", kmh.mh_cavity), (kmh, "scatter_vector", kmh.scatter_vector),
             (fmh, "scatter_band", fmh.scatter_band), (fmh, "factor_bordered", fmh.factor_bordered),
             (kmb, "bordered_factor_into", kmb.bordered_factor_into),
             (fmodel.BorderedSolver, "solve", fmodel.BorderedSolver.solve)]
    kmh.mh_elements = wrap("", kmh.mh_elements, key=lambda a: "elements, tangent" if a[15] >= 2 else
                           "elements, energy/residual")
    kmh.mh_assemble_band = wrap("elements, tangent", kmh.mh_assemble_band)
    kmh.mh_cavity = wrap("cavity", kmh.mh_cavity)
    kmh.scatter_vector = wrap("scatter", kmh.scatter_vector)
    fmh.scatter_band = wrap("scatter", fmh.scatter_band)
    fmh.factor_bordered = wrap("bordered LDL^T", fmh.factor_bordered)
    kmb.bordered_factor_into = wrap("bordered LDL^T", kmb.bordered_factor_into)
    fmodel.BorderedSolver.solve = wrap("bordered solves", fmodel.BorderedSolver.solve)
    try:
        yield acc
    finally:
        for obj, attr, fn in saved:
            setattr(obj, attr, fn)


def load_kernel(path: Path | None):
    """The element kernel module of the "before" runs: a copy of the kernel source file ``path``
    (e.g. the main branch's ``kernels/multiharmonic.py``) in ``bench/out/follow_profile_before/``,
    imported from there (so that its numba cache lives there, not beside ``path``), or ``None``
    for the library's own :mod:`snapjump_kernels.multiharmonic`."""
    if path is None:
        import snapjump_kernels.multiharmonic as kmh

        return kmh
    import importlib.util

    folder = Path(__file__).resolve().parent / "out" / "follow_profile_before"
    folder.mkdir(parents=True, exist_ok=True)
    copy = folder / "before_multiharmonic.py"
    text = Path(path).read_text()
    if not copy.is_file() or copy.read_text() != text:
        copy.write_text(text)
    spec = importlib.util.spec_from_file_location("before_multiharmonic", str(copy))
    mod = importlib.util.module_from_spec(spec)
    sys.modules["before_multiharmonic"] = mod  # importable by name (numba's cache rebuilds its environment so)
    spec.loader.exec_module(mod)
    return mod


@contextmanager
def mode(which: str, before_kernel=None):
    """``"after"``: the library as it is. ``"before"``: the model's assembly and factorisation of
    2026-11-27 (:attr:`MultiHarmonicModel.fused_assembly` False: element matrices, ``scatter_band``,
    ``factor_bordered`` into fresh arrays) with the element kernel ``before_kernel.mh_elements``
    (:func:`load_kernel`). ``"reference"``: as ``"before"`` with the element kernel before
    2026-11-27 (:mod:`snapjump_kernels.multiharmonic_reference`)."""
    import snapjump_kernels.multiharmonic as kmh
    from snapjump_cli.fe.branch.model import MultiHarmonicModel

    saved = kmh.mh_elements, MultiHarmonicModel.fused_assembly
    try:
        if which != "after":
            MultiHarmonicModel.fused_assembly = False
            if which == "reference":
                from snapjump_kernels.multiharmonic_reference import mh_elements_reference

                kmh.mh_elements = lambda *a: mh_elements_reference(*a, 5)
            elif before_kernel is not None:
                kmh.mh_elements = before_kernel.mh_elements
        yield
    finally:
        kmh.mh_elements, MultiHarmonicModel.fused_assembly = saved


def whole_solve(res, bif, hn, which: str = "after", before_kernel=None) -> tuple[dict, object]:
    """The followed solve with every kernel call timed; returns the times and the result."""
    from snapjump_cli.fe.branch.trace import follow_branch

    acc: dict = {}
    with mode(which, before_kernel):
        with instrumented(acc):
            t0 = time.process_time()
            fr = follow_branch(res, bif, hn)
            acc["total"] = time.process_time() - t0
    return acc, fr


def one_assembly(mh, u: np.ndarray, p: float, repeat: int, which: str = "after",
                 before_kernel=None) -> dict[str, float]:
    """Median CPU seconds of each phase of one tangent assembly and LDL^T at ``(u, p)``, as the
    model does it in mode ``which`` (:func:`mode`)."""
    from snapjump_kernels.calls import bordered_factor, scatter_band
    from snapjump_kernels.multiharmonic import mh_assemble_band, mh_cavity, scatter_vector
    from snapjump_kernels.multiharmonic_band import bordered_factor_into

    if which == "reference":
        from snapjump_kernels.multiharmonic_reference import mh_elements_reference as phases
    else:
        kern = before_kernel if (which == "before" and before_kernel is not None) else load_kernel(None)
        phases = kern.mh_elements_phases
    M = mh.base
    A = np.ascontiguousarray(mh.total_amplitudes(u))

    def elements(upto: int, want: int = 2):
        return phases(A, M.conn, M.mat, M.mu, M.jm, M.kappa, M.dNdX, M.N_ref, M.Rq, M.Wq, M.Np, M.Minv,
                      mh.hn, mh.phis, mh.wphi, want, mh.Fi, mh.Jimp, mh.Minvp, upto)

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
    ext = mh.band_ext
    buf = np.zeros((mh.n, mh.kl + 1))

    def vectors():
        R = np.zeros(mh.n)
        scatter_vector(re, mh.edofs, mh.ecoef, 1.0, R)
        scatter_vector(ge, mh.gdofs, mh.gcoef, 1.0, R)

    if which == "after":
        def fused():
            mh_assemble_band(A, M.conn, M.mat, M.mu, M.jm, M.kappa, M.dNdX, M.N_ref, M.Rq, M.Wq, M.Np, M.Minv,
                             mh.hn, mh.phis, mh.wphi, mh.Fi, mh.Jimp, mh.Minvp, mh.edofs, mh.ecoef, ext, buf)

        def scatter():
            vectors()
            scatter_band(He, mh.gdofs, mh.gcoef, -float(p), buf)

        fused()
        t_fused = _median_cpu(fused, repeat)
        out["scatter to band"] = _median_cpu(scatter, repeat) + t_fused - out["elements, all (want 2)"]
        ab = buf.copy()
        fac = np.zeros_like(ab)
        zeros = np.zeros(mh.n)

        def ldlt():  # the envelope copied into the buffer, LDL^T and K^-1 b
            bordered_factor_into(ab, ext, zeros, zeros, 1.0, fac)

        ldlt()
        out["band LDL^T (bordered, with Kib)"] = _median_cpu(ldlt, repeat)
        t_el = t_fused
        t_sc = out["scatter to band"] - (t_fused - out["elements, all (want 2)"])
    else:
        def scatter():
            vectors()
            ab = np.zeros((mh.n, mh.kl + 1))
            scatter_band(Ke, mh.edofs, mh.ecoef, 1.0, ab)
            scatter_band(He, mh.gdofs, mh.gcoef, -float(p), ab)
            return ab

        out["scatter to band"] = _median_cpu(scatter, repeat)
        ab = scatter()
        bordered_factor(ab, ext, np.zeros(mh.n), np.zeros(mh.n), 1.0)
        out["band LDL^T (bordered, with Kib)"] = _median_cpu(
            lambda: bordered_factor(ab, ext, np.zeros(mh.n), np.zeros(mh.n), 1.0), repeat)
        t_el = out["elements, all (want 2)"]
        t_sc = out["scatter to band"]
    with mode(which, before_kernel):
        mh.linearize(u, p)
        out["linearize (all of the above but LDL^T)"] = _median_cpu(lambda: mh.linearize(u, p), repeat)
    out["Python glue of linearize"] = (out["linearize (all of the above but LDL^T)"] - t_el
                                       - out["cavity (want 2)"] - t_sc)
    out["one assembly + LDL^T"] = out["linearize (all of the above but LDL^T)"] + out["band LDL^T (bordered, with Kib)"]
    return out


def axisymmetric(name: str) -> float:
    """CPU seconds of the scene's axisymmetric solve and harmonic check (``n <= 4``): one call of
    :func:`bench.follow_study.solve_checked_scene`, meshing included."""
    from bench.follow_study import solve_checked_scene

    t0 = time.process_time()
    solve_checked_scene(name)
    return time.process_time() - t0


KEYS = ("dE_J", "dy_pole_m", "V_star_m3", "p_star_Pa")


def warm(res, bif, hn, modes, before_kernel=None) -> None:
    """Compile every kernel the followed solve calls in each mode (three steps of the branch), so
    that no timing includes a JIT compilation."""
    from snapjump_cli.fe.branch.trace import follow_branch

    for which in modes:
        with mode(which, before_kernel):
            follow_branch(res, bif, hn, max_steps=3)


def compare(name: str, res, bif, hn, before_kernel=None, rounds: int = 2, before: str = "before") -> float:
    """Follow the branch from one located bifurcation "after" and "before" (:func:`mode`),
    alternated ``rounds`` times in this process (``before``: ``"before"`` or ``"reference"``), with the scene's axisymmetric solve and check
    timed between them (back to back, at the same load); print each run's answers, CPU, steps and
    assemblies; return the largest relative difference of the answers."""
    from snapjump_cli.fe.branch.trace import follow_branch

    warm(res, bif, hn, (before, "after"), before_kernel)
    runs: dict[str, list] = {"after": [], before: [], "axisymmetric": []}
    for r in range(rounds):
        for which in ("after", before, "axisymmetric"):
            if which == "axisymmetric":
                t = axisymmetric(name)
                runs[which].append({"cpu_s": t})
                print(f"axisymmetric solve + check: {t:.3f} CPU-s", flush=True)
                continue
            with mode(which, before_kernel):
                t0 = time.process_time()
                fr = follow_branch(res, bif, hn)
                row = {k: fr.metrics.get(k) for k in KEYS}
                row.update(cpu_s=time.process_time() - t0, steps=len(fr.path.points) - 1,
                           assemblies=fr.model.n_assemblies)
            runs[which].append(row)
            print(which, json.dumps(row), flush=True)
    ref = runs[before][0]
    diff = max(abs(x[k] - ref[k]) / abs(ref[k]) for w in ("after", before) for x in runs[w] for k in KEYS)
    axi = statistics.median(x["cpu_s"] for x in runs["axisymmetric"])
    for w in (before, "after"):
        cpu = statistics.median(x["cpu_s"] for x in runs[w])
        print(f"{w}: followed {cpu:.2f} CPU-s (median of {rounds}), axisymmetric solve + check {axi:.3f} CPU-s: "
              f"{cpu / axi:.1f}x")
    print(f"largest relative difference of the answers, every run against the first '{before}': {diff:.3g}")
    return diff


def envelope_flops(mh) -> float:
    """Flops of the band LDL^T on the model's envelope (``sum_j ext_j (ext_j + 3)``)."""
    e = np.asarray(mh.band_ext, float)
    return float(np.sum(e * (e + 3.0)))


def step_growth(res, bif, hn, grows: list[float]) -> None:
    """The followed branch with the continuation's step growth (``follow_branch(step_grow=...)``,
    default :data:`snapjump_cli.fe.branch.trace.FOLLOW_STEP_GROW`; the axisymmetric trace's is 1.6) set
    to each of ``grows`` in turn; prints the steps, rejected steps, assemblies, CPU and the
    answers' relative differences from the first run."""
    from snapjump_cli.fe.branch.trace import follow_branch

    first = None
    for g in grows:
        t0 = time.process_time()
        fr = follow_branch(res, bif, hn, step_grow=float(g))
        cpu = time.process_time() - t0
        m = {k: fr.metrics.get(k) for k in KEYS}
        first = first or m
        diff = max(abs(m[k] - first[k]) / abs(first[k]) for k in KEYS)
        print(f"step growth {g}: {len(fr.path.points) - 1} steps, {fr.path.n_rejected} rejected, "
              f"{fr.model.n_assemblies} assemblies, {cpu:.2f} CPU-s; answers differ from the first run's by "
              f"{diff:.2g} (relative)", flush=True)


#: why this profile no longer runs (issue 35): the hooks it times were removed from the product
RETIRED = ("bench.follow_profile needs the profiling hooks that issue 35 removed from the product (the element "
           "kernel's upto / mh_elements_phases, MultiHarmonicModel.fused_assembly, kernels/multiharmonic_reference.py); "
           "run it on commit 51d9ff8 (git worktree add /tmp/fp 51d9ff8)")


def main(argv=None) -> int:
    sys.exit(RETIRED)
    from snapjump_cli.fe.branch.bifurcation import default_harmonics

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", nargs="?", default="B")
    ap.add_argument("--N", type=int, default=0, help="highest harmonic kept (default 4 n_c)")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--before", type=Path, default=None,
                    help="the element kernel source of the 'before' runs (e.g. the main branch's "
                         "kernels/multiharmonic.py; default the library's)")
    ap.add_argument("--reference", action="store_true",
                    help="'before' with the element kernel before 2026-11-27 (multiharmonic_reference)")
    ap.add_argument("--compare", action="store_true",
                    help="only the whole branch, after and before alternated, with the axisymmetric solve")
    ap.add_argument("--rounds", type=int, default=2, help="alternations of --compare")
    ap.add_argument("--step-grow", type=float, nargs="+", default=None,
                    help="instead: the branch with the continuation's step growth set to each value in turn")
    ap.add_argument("--json", type=Path, default=None, help="also write the numbers here")
    a = ap.parse_args(argv)
    before_kernel = load_kernel(a.before) if a.before else None
    before = "reference" if a.reference else "before"
    res, bif, t_first = setup(a.scene)
    print(f"axisymmetric solve + check, the first call in this process: {t_first:.3f} CPU-s")
    hn = default_harmonics(bif.n, a.N or None)
    if a.step_grow:
        step_growth(res, bif, hn, a.step_grow)
        return 0
    if a.compare:
        compare(a.scene, res, bif, hn, before_kernel, a.rounds, before)
        return 0
    warm(res, bif, hn, (before, "after"), before_kernel)
    whole, one, frs = {}, {}, {}
    for which in (before, "after"):
        whole[which], frs[which] = whole_solve(res, bif, hn, which, before_kernel)
    t_axi = axisymmetric(a.scene)
    fr = frs["after"]
    mh = fr.model
    n_assemblies = mh.n_assemblies
    pts = fr.path.points
    mid = pts[len(pts) // 2]
    for which in ("after", before, "after", before):
        o = one_assembly(mh, mid.u, mid.p, a.repeat, which, before_kernel)
        one[which] = o if which not in one else {k: min(v, one[which][k]) for k, v in o.items()}
    M = mh.base
    ne, nen = M.conn.shape
    fl = tangent_flops(ne, nen, M.Wq.shape[1], M.Np.shape[1], len(hn), len(mh.phis))
    print(f"## {a.scene}: harmonics {hn}, {mh.n} dofs, {ne} elements of {nen} nodes, {len(mh.phis)} phi points, "
          f"band kl {mh.kl}, mean envelope {np.mean(mh.band_ext):.1f}; 'before': "
          f"{'the kernel before 2026-11-27' if a.reference else (a.before or 'the library kernel')} "
          f"with the assembly and factorisation of 2026-11-27\n")
    gfl = {"elements: " + PHASES[2]: fl["moments"], "elements: " + PHASES[3]: fl["btdb"],
           "elements: " + PHASES[4]: fl["volumetric"], "band LDL^T (bordered, with Kib)": envelope_flops(mh)}
    print(f"| one assembly (middle of the path), CPU ms (the better of 2 medians of {a.repeat}) | before | after "
          "| Gflop | GFlop/s before | after |")
    print("|---|---|---|---|---|---|")
    for k in one["after"]:
        v0, v1 = one[before][k], one["after"][k]
        f = gfl.get(k)
        fs = f"{f / 1e9:.3f}" if f else ""
        r0 = f"{f / 1e9 / v0:.1f}" if f and v0 > 0 else ""
        r1 = f"{f / 1e9 / v1:.1f}" if f and v1 > 0 else ""
        print(f"| {k} | {1e3 * v0:.2f} | {1e3 * v1:.2f} | {fs} | {r0} | {r1} |")
    print(f"\n| whole followed solve (N = {hn[-1]}), CPU s | before | after | calls after |")
    print("|---|---|---|---|")
    for k in ("elements, tangent", "elements, energy/residual", "cavity", "scatter", "bordered LDL^T",
              "bordered solves"):
        print(f"| {k} | {whole[before].get(k, 0.0):.2f} | {whole['after'].get(k, 0.0):.2f} | "
              f"{whole['after'].get('n ' + k, 0)} |")
    rest = {w: whole[w]["total"] - sum(whole[w].get(k, 0.0) for k in ("elements, tangent", "elements, energy/residual",
                                                                       "cavity", "scatter", "bordered LDL^T",
                                                                       "bordered solves")) for w in whole}
    print(f"| continuation, Python and the rest | {rest[before]:.2f} | {rest['after']:.2f} | |")
    print(f"| **total** | **{whole[before]['total']:.2f}** | **{whole['after']['total']:.2f}** | "
          f"{len(pts) - 1} steps, {n_assemblies} assemblies |")
    same = all(frs["after"].metrics.get(k) == frs[before].metrics.get(k) for k in KEYS)
    print(f"\naxisymmetric solve + check {t_axi:.3f} CPU-s (warm; the first call {t_first:.3f}); followed / axisymmetric: before "
          f"{whole[before]['total'] / t_axi:.1f}x, after {whole['after']['total'] / t_axi:.1f}x; answers "
          f"{'identical' if same else 'DIFFERENT'}: " + ", ".join(f"{k} {fr.metrics.get(k)!r}" for k in KEYS))
    if a.json:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        a.json.write_text(json.dumps({"scene": a.scene, "hn": hn, "ndof": mh.n, "one_assembly_s": one,
                                      "whole_solve_s": whole, "steps": len(pts) - 1, "assemblies": n_assemblies,
                                      "cpu_axisym_check_s": t_axi, "cpu_axisym_check_first_s": t_first, "flops": fl,
                                      "metrics": {w: frs[w].metrics for w in frs}}, indent=1, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
