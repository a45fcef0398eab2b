"""CPU cost of the harmonic check (docs/harmonics.md sections 6 and 8), phase by phase, on a fixed
sample, and the check's answers for an exact before/after comparison.

    .venv/bin/python -m bench.check_profile [--limit N] [--n-max 4] [--out rows.json]
    .venv/bin/python -m bench.check_profile --design D [--design C] [--repeat 5]
    .venv/bin/python -m bench.check_profile compare OLD.json NEW.json

Each design of the sample (default: the 480 seeded paper-grid points of
``bench/harmonics_sample/points.csv``, the first ``--limit``) is solved as the sweep solves it with
the check off (``solve_checked`` with the sweep's short mesh re-check), then
:func:`snapjump_cli.fe.stability.harmonics.check_harmonics` runs on the result. Both are timed in process
CPU time (``time.process_time``; one process, one BLAS thread, as a sweep worker runs), so the
figures do not depend much on other jobs on the machine. The phases of the check are timed by
wrapping the functions it calls (exclusive times: a phase's callees are counted in theirs):

* ``K_n elements``: the element matrices of ``K_n`` (``harmonic_element_matrices``, one call
  per harmonic; since 2026-11-27 ``harmonic_element_parts``, one call per state for every harmonic);
* ``band``: the scatter into the band with the cavity load stiffness (``scatter_band``,
  ``harmonic_cavity_matrices``; now ``harmonic_band``, with the shift and the gauge rows);
* ``LDL^T``: the band factorisations (``band_ldlt``);
* ``gauge``: the choice of the rigid-mode gauge dofs of ``n = 1`` (``gauge_dofs``);
* ``refine Newton``: the Newton solves of the onset's bisection (``tracer.correct``);
* ``Python glue``: the rest of the check.

``--design NAME`` profiles named designs instead, at the default mesh (as ``snapjump curve``
solves them); ``--repeat R`` runs the check R times on each solved design (the CPU figures are
the totals over the repeats).

``--out`` writes each design's ``asym_*`` answers with its CPU times; ``compare`` counts the
designs whose answers differ between two such files (the flags and harmonics exactly, the onset's
volume and pressure by their relative change).
"""
from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # one thread, as a sweep worker
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import csv  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from bench.cases import json_value  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
POINTS = REPO / "bench" / "harmonics_sample" / "points.csv"
GRID = REPO / "configs" / "paper_grid.yaml"
#: Answers that must be identical before and after a change of the check's implementation.
EXACT = ("asym_first", "asym_n", "asym_ns", "asym_lower_stable", "asym_lower_n", "asym_states_checked")
#: Answers compared by their relative change.
CLOSE = ("asym_V_m3", "asym_p_Pa")
#: phase -> names (module globals of snapjump_cli.fe.stability.harmonics) whose calls it times; the first
#: phase of a name that exists wins, so that older and newer versions of the module both profile.
PHASES: dict[str, tuple[str, ...]] = {
    "K_n elements": ("harmonic_element_matrices", "harmonic_element_parts"),
    "band": ("harmonic_cavity_matrices", "scatter_band", "harmonic_band"),
    "LDL^T": ("band_ldlt",),
}
ORDER = ("K_n elements", "band", "LDL^T", "gauge", "refine Newton", "Python glue")


class PhaseTimer:
    """Exclusive CPU time per phase: a wrapped call's time minus that of the wrapped calls it makes."""

    def __init__(self) -> None:
        self.cpu: dict[str, float] = {k: 0.0 for k in ORDER}
        self.calls: dict[str, int] = {k: 0 for k in ORDER}
        self._stack: list[float] = []  # the callee time accumulated by each open call

    def add(self, phase: str, dt: float) -> None:
        """Count one call of ``phase`` taking ``dt`` CPU seconds of its own."""
        self.cpu[phase] += dt
        self.calls[phase] += 1

    def wrap(self, phase: str, f):
        """``f``, timed into ``phase`` (:meth:`add`)."""

        def timed(*args, **kwargs):
            self._stack.append(0.0)
            t0 = time.process_time()
            try:
                return f(*args, **kwargs)
            finally:
                dt = time.process_time() - t0
                inner = self._stack.pop()
                self.add(phase, dt - inner)
                if self._stack:
                    self._stack[-1] += dt

        timed.__wrapped__ = f
        return timed


def install(timer: PhaseTimer) -> None:
    """Wrap the check's callees (module globals of :mod:`snapjump_cli.fe.stability.harmonics`, the gauge)."""
    from snapjump_cli.fe.stability import harmonics as H

    for phase, names in PHASES.items():
        for name in names:
            if hasattr(H, name):
                setattr(H, name, timer.wrap(phase, getattr(H, name)))
    H.HarmonicOperator.gauge_dofs = timer.wrap("gauge", H.HarmonicOperator.gauge_dofs)


def sample(limit: int | None) -> list[dict]:
    """The sample's designs (``id`` and the keyword arguments of ``Design``)."""
    from snapjump_cli.sweep.config import load_config

    cfg = load_config(GRID)
    fixed = dict(R_i=cfg.R_i, mu_i=cfg.mu_i, J_m=cfg.J_m, t_ring_frac=cfg.t_ring_frac, w_ring_frac=cfg.w_ring_frac)
    out = []
    with open(POINTS, newline="") as fh:
        for i, r in enumerate(csv.DictReader(fh)):
            out.append({"id": f"s{i:03d}", "params": dict(eta_i=float(r["eta_i"]), theta_i_deg=float(r["theta_i"]),
                                                          eta_o=float(r["eta_o"]), theta_o_deg=float(r["theta_o"]),
                                                          mu_ratio=float(r["mu_ratio"]), **fixed)})
    return out[:limit] if limit else out


def run(limit: int | None, n_max: int, out: Path | None, designs: list[str] | None = None, repeat: int = 1) -> int:
    from snapjump_cli.fe.stability.harmonics import check_harmonics
    from snapjump_cli.fe.solve import SolveFailed, solve_checked, warm_up
    from snapjump_cli.geometry.caps import Design, InvalidDesign
    from snapjump_cli.sweep.config import load_config

    cfg = load_config(GRID)
    solver = dataclasses.replace(cfg.solver, harmonics=0)
    warm_up()
    timer = PhaseTimer()
    install(timer)
    items = sample(limit) if not designs else [{"id": name, "name": name} for name in designs]
    if designs:
        from snapjump_cli.geometry.designs import get_design
        from snapjump_cli.settings import MeshSettings

        cfg = cfg.replace(mesh=MeshSettings())

    def design(it):
        return get_design(it["name"]) if "name" in it else Design(**it["params"])
    # compile (or load) the check's kernels outside the timings
    for it in items:
        try:
            check_harmonics(solve_checked(design(it), cfg.mesh, solver, short_recheck=True), n_max)
            break
        except (InvalidDesign, SolveFailed):
            continue
    timer.__init__()
    rows, t_solve, t_check, n_states = [], 0.0, 0.0, 0
    for it in items:
        row = {"id": it["id"], "params": it.get("params")}
        try:
            d = design(it)
        except InvalidDesign:
            rows.append({**row, "status": "invalid_geometry"})
            continue
        t0 = time.process_time()
        try:
            res = solve_checked(d, cfg.mesh, solver, short_recheck=True)
        except SolveFailed as e:
            rows.append({**row, "status": "failed", "error": str(e)[:200]})
            continue
        t1 = time.process_time()
        tracer = getattr(res, "tracer", None)
        if tracer is not None:
            tracer.correct = timer.wrap("refine Newton", tracer.correct)
        t2 = time.process_time()
        h = check_harmonics(res, n_max)
        for _ in range(repeat - 1):
            check_harmonics(res, n_max)
        t3 = time.process_time()
        t_solve += t1 - t0
        t_check += t3 - t2
        n_states += repeat * h.asym_states_checked
        row.update(status="ok" if res.metrics.get("snaps") else "no_snap", solve_cpu_s=t1 - t0, check_cpu_s=t3 - t2)
        row.update({k: json_value(h.get(k)) for k in EXACT + CLOSE})
        rows.append(row)
    timer.cpu["Python glue"] = t_check - sum(v for k, v in timer.cpu.items() if k != "Python glue")
    checked = [r for r in rows if "check_cpu_s" in r]
    what = ", ".join(designs) + " (default mesh)" if designs else str(POINTS.relative_to(REPO))
    print(f"sample: {len(items)} designs ({what}), {len(checked)} checked x {repeat} "
          f"(n <= {n_max}), {n_states} states ({n_states / max(len(checked), 1):.1f} per design); "
          f"load average {os.getloadavg()[0]:.2f}")
    print(f"CPU: solve with the check off {t_solve:.2f} s, the check {t_check:.2f} s "
          f"(+{100 * t_check / max(t_solve, 1e-9):.0f} %); per checked state {1e3 * t_check / max(n_states, 1):.2f} ms\n")
    print("| phase | CPU-s | share | calls | ms per call |\n|---|---|---|---|---|")
    for k in ORDER:
        c = timer.calls[k]
        print(f"| {k} | {timer.cpu[k]:.2f} | {100 * timer.cpu[k] / max(t_check, 1e-9):.0f} % | "
              f"{c if c else '-'} | {f'{1e3 * timer.cpu[k] / c:.3f}' if c else '-'} |")
    print(f"| **the check** | **{t_check:.2f}** | 100 % | {len(checked)} designs | "
          f"{1e3 * t_check / max(len(checked), 1):.1f} per design |")
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps({"n_max": n_max, "solve_cpu_s": t_solve, "check_cpu_s": t_check,
                                   "phases": timer.cpu, "rows": rows}, indent=1) + "\n")
        print(f"\nwrote {out}")
    return 0


def compare(old: Path, new: Path) -> int:
    """Count the designs whose check answers differ between two ``--out`` files; exit 1 if a flag,
    a harmonic or the number of checked states differs."""
    a = {r["id"]: r for r in json.loads(old.read_text())["rows"]}
    b = {r["id"]: r for r in json.loads(new.read_text())["rows"]}
    common = sorted(set(a) & set(b))
    diff = {k: [] for k in ("status",) + EXACT}
    rel = {k: 0.0 for k in CLOSE}
    for i in common:
        for k in diff:
            if a[i].get(k) != b[i].get(k):
                diff[k].append(i)
        for k in CLOSE:
            x, y = a[i].get(k), b[i].get(k)
            if (x is None) != (y is None):
                rel[k] = math.inf
            elif x is not None:
                rel[k] = max(rel[k], abs(y - x) / max(abs(x), 1e-300))
    print(f"{len(common)} designs in both ({len(a)} / {len(b)}); "
          f"checked: {sum('check_cpu_s' in b[i] for i in common)}")
    for k, ids in diff.items():
        print(f"{k}: {len(ids)} differ" + (f" ({', '.join(ids[:10])})" if ids else ""))
    for k, v in rel.items():
        print(f"{k}: largest relative change {v:.3g}")
    ca, cb = (json.loads(p.read_text())["check_cpu_s"] for p in (old, new))
    print(f"check CPU: {ca:.2f} s -> {cb:.2f} s ({cb / max(ca, 1e-9):.2f}x)")
    return 1 if any(diff.values()) else 0


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["compare"]:
        ap = argparse.ArgumentParser(prog="python -m bench.check_profile compare")
        ap.add_argument("old", type=Path)
        ap.add_argument("new", type=Path)
        a = ap.parse_args(argv[1:])
        return compare(a.old, a.new)
    ap = argparse.ArgumentParser(prog="python -m bench.check_profile", description=__doc__.split("\n\n")[0])
    ap.add_argument("--limit", type=int, default=None, help="the first N designs of the sample (default: all 480)")
    ap.add_argument("--n-max", type=int, default=4, help="highest harmonic checked (default 4, the grid's)")
    ap.add_argument("--out", type=Path, default=None, help="write the answers and CPU times (JSON)")
    ap.add_argument("--design", action="append", default=None, help="a named design instead of the sample (repeatable)")
    ap.add_argument("--repeat", type=int, default=1, help="run the check this many times per design")
    a = ap.parse_args(argv)
    return run(a.limit, a.n_max, a.out, a.design, max(1, a.repeat))


if __name__ == "__main__":
    raise SystemExit(main())
