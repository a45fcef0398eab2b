"""The element pass (:func:`snapjump_kernels.assembly.assemble`) of this checkout against the one
of an older commit, in one process: CPU time per call (the minimum over repeats, the two kernels
timed alternately) and the largest differences of energy, force and stiffness.

    PYTHONPATH=.:.shim python scripts/elem_bench.py [--base REV] [--designs D C] [--calls 500] [--repeat 7]

The base commit's ``kernels/`` is unpacked (``git archive``) into a directory under the system's
temporary directory as the package ``snapjump_kernels_base`` (kept, so that its numba cache
survives between runs). The state is the middle point of each design's path at the paper grid's
mesh (``solve_scene``); ``want`` 2 is timed both with the reduced tangent (no element pressures
passed in) and with the mixed one the corrector uses (``p_geo``, ``pb_out``, ``H_out``).
"""
from __future__ import annotations

import argparse
import importlib
import io
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]


def base_kernels(rev: str):
    """The ``assembly`` module of commit ``rev``, importable next to this checkout's."""
    sha = subprocess.run(["git", "-C", str(REPO), "rev-parse", rev], check=True, capture_output=True,
                         text=True).stdout.strip()
    root = Path(tempfile.gettempdir()) / f"snapjump_elem_base_{sha[:12]}"
    pkg = root / "snapjump_kernels_base"
    if not pkg.is_dir():
        tar = subprocess.run(["git", "-C", str(REPO), "archive", sha, "kernels"], check=True,
                             capture_output=True).stdout
        pkg.mkdir(parents=True)
        with tarfile.open(fileobj=io.BytesIO(tar)) as t:
            for m in t.getmembers():
                if m.isfile() and m.name.endswith(".py"):
                    src = t.extractfile(m).read().decode()
                    src = src.replace("snapjump_kernels.", "snapjump_kernels_base.")
                    (pkg / Path(m.name).name).write_text(src)
    sys.path.insert(0, str(root))
    return importlib.import_module("snapjump_kernels_base.assembly"), sha[:12]


def state(name: str):
    from snapjump_cli.sweep.config import load_config
    from snapjump_cli.geometry.designs import get_design
    from snapjump_cli.geometry.caps import Design
    from snapjump_cli.fe.solve import solve_scene

    cfg = load_config(REPO / "configs" / "paper_grid.yaml")
    if name.startswith("grid-"):
        d = Design(**list(cfg.designs())[int(name[5:])].design_kwargs())
    else:
        d = get_design(name)
    r = solve_scene(d, cfg.mesh, cfg.solver)
    m = r.model
    pt = r.path.points[len(r.path.points) // 2]
    return m, m.full_displacement(pt.u)


def make_call(mod, m, U, want, mixed):
    ne, npr, nd = m.conn.shape[0], m.Np.shape[1], m.edofs.shape[1]
    f = np.zeros(m.n)
    data = np.zeros(m.ndata if want >= 2 else 1)
    if mixed:
        pb, H = np.zeros((ne, npr)), np.zeros((ne, npr, nd))
    else:
        p_geo, pb, H = np.zeros((0, npr)), np.zeros((0, npr)), np.zeros((0, npr, nd))
    if mixed:  # the element pressures at U, perturbed: a p_geo that differs from kappa M^-1 g(u)
        mod.assemble(U, m.conn, m.mat, m.mu, m.jm, m.kappa, m.dNdX, m.N_ref, m.Rq, m.Wq, m.Np, m.Minv,
                     m.edofs, m.epos, 1, f, data, np.zeros((0, npr)), pb, np.zeros((0, npr, nd)))
        p_geo = pb * 1.01 + 1e-3

    def call():
        f[:] = 0.0
        data[:] = 0.0
        return mod.assemble(U, m.conn, m.mat, m.mu, m.jm, m.kappa, m.dNdX, m.N_ref, m.Rq, m.Wq, m.Np, m.Minv,
                            m.edofs, m.epos, want, f, data, p_geo, pb, H)

    def result():
        E, ok, dev = call()
        return E, ok, dev, f.copy(), data.copy(), pb.copy(), H.copy()

    return call, result


def per_call(call, calls):
    t0 = time.process_time()
    for _ in range(calls):
        call()
    return 1e6 * (time.process_time() - t0) / calls


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--base", default="ab119c4", help="the commit to compare with")
    ap.add_argument("--designs", nargs="*", default=["D", "C"])
    ap.add_argument("--calls", type=int, default=500)
    ap.add_argument("--repeat", type=int, default=7)
    a = ap.parse_args(argv)
    import snapjump_kernels.assembly as new
    old, sha = base_kernels(a.base)
    for name in a.designs:
        m, U = state(name)
        print(f"{name}: {m.conn.shape[0]} elements, {m.n} dofs; us (CPU) per call, min of {a.repeat} x "
              f"{a.calls} calls, base {sha} -> this checkout")
        for want, mixed, label in ((2, False, "stiffness"), (2, True, "stiffness, mixed"),
                                   (1, False, "residual"), (0, False, "energy")):
            c_old, r_old = make_call(old, m, U, want, mixed)
            c_new, r_new = make_call(new, m, U, want, mixed)
            c_old(), c_new()
            t_old, t_new = [], []
            for k in range(a.repeat):  # alternately, each one first every other time
                for c, t in ((c_old, t_old), (c_new, t_new))[::1 if k % 2 else -1]:
                    t.append(per_call(c, a.calls))
            ro, rn = r_old(), r_new()
            assert ro[1] and rn[1]

            def rel(x, y):
                return float(np.abs(x - y).max() / max(np.abs(x).max(), 1e-300)) if x.size else 0.0

            diffs = (f"energy {abs(ro[0] - rn[0]) / abs(ro[0]):.1e}, force {rel(ro[3], rn[3]):.1e}, "
                     f"stiffness {rel(ro[4], rn[4]):.1e}, max dilatation {abs(ro[2] - rn[2]) / ro[2]:.1e}")
            if mixed:
                diffs += f", pb {rel(ro[5], rn[5]):.1e}, H {rel(ro[6], rn[6]):.1e}"
            print(f"  {label}: {min(t_old):.1f} -> {min(t_new):.1f} ({min(t_old) / min(t_new):.2f}x); "
                  f"largest difference (relative to the largest entry): {diffs}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
