"""The numerical stress suite (``make stress``; marked ``stress``, deselected from ``make test``).

1. The whole paper grid (configs/paper_grid.yaml, 4800 designs) through the real sweep.
2. 1000 random designs over the extended domain (theta_i 40-85, eta_i 5-30, theta_o 40-90,
   eta_o 5-30, mu_i/mu_o 1-20).
3. Invariance on a sample of paper-grid designs: dE changes by <= 0.5 % with the initial arc length
   x0.25 and x4 and with the Newton tolerance tightened 10x; two identical runs are bitwise identical.

Every sweep asserts the row contract (no unhandled exception, every non-ok row classified with its
cause, no NaN/inf in an ok row), and writes a summary (counts, failure rate, causes) next to its
resumable result file in ``results/stress/`` (``SNAPJUMP_STRESS_DIR``). The full run took ~15 min
on a 2-core machine (bench/README.md): it resumes where a killed run stopped. Knobs
(sample sizes, mesh, jobs): see ``stresslib``.
"""
from __future__ import annotations

import pytest

import stresslib as sl
from snapjump_cli.settings import SolverSettings

pytestmark = pytest.mark.stress


def _tag() -> str:
    m = sl.mesh_settings()
    return f"o{m.order}nt{m.nt}a{m.aspect:g}"


def _finish(df, title: str, name: str, stress_report) -> None:
    text = sl.summarize(df, title)
    (sl.out_dir() / f"{name}.summary.md").write_text(text + "\n")
    stress_report(text)
    bad = sl.check_rows(df)
    assert not bad, f"{len(bad)} row-contract violations, first ones:\n" + "\n".join(bad[:20])


def test_paper_grid(stress_report):
    """The whole paper grid through the sweep; or, with ``SNAPJUMP_STRESS_GRID_RESULTS`` set to
    the parquet of a finished ``snapjump sweep configs/paper_grid.yaml``, that run checked as is
    (the same row contract, and every grid point present exactly once)."""
    import os

    existing = os.environ.get("SNAPJUMP_STRESS_GRID_RESULTS", "").strip()
    if existing:
        from pathlib import Path

        from snapjump_cli.sweep import results as res

        df = res.read_results(Path(existing))
        pts = sl.paper_grid_points(None)
        got = {tuple(round(float(r[k]), 9) for k in ("eta_i", "theta_i_deg", "eta_o", "theta_o_deg", "mu_ratio"))
               for _, r in df.iterrows()}
        want = {tuple(round(float(p[k]), 9) for k in ("eta_i", "theta_i_deg", "eta_o", "theta_o_deg", "mu_ratio"))
                for p in pts}
        assert len(df) == len(pts) and df["key"].is_unique and got == want
        m = df.iloc[0]
        tag = f"o{m['mesh_order']}nt{m['mesh_nt']}a{float(m['mesh_aspect']):g}"
        _finish(df, f"paper grid ({len(pts)} designs, mesh {tag}, from {existing})", f"paper_grid_{tag}_existing",
                stress_report)
        return
    sample = sl.env_int("SNAPJUMP_STRESS_GRID_SAMPLE", 0) or None
    seed = sl.env_int("SNAPJUMP_STRESS_SEED", 5)
    pts = sl.paper_grid_points(sample, seed)
    name = f"paper_grid_{_tag()}" + (f"_sample{sample}_seed{seed}" if sample else "")
    df = sl.sweep(pts, sl.out_dir() / f"{name}.parquet")
    assert len(df) == len(pts) and df["key"].is_unique
    _finish(df, f"paper grid ({len(pts)} designs, mesh {_tag()})", name, stress_report)


def test_random_extended_domain(stress_report):
    n = sl.env_int("SNAPJUMP_STRESS_N", 1000)
    seed = sl.env_int("SNAPJUMP_STRESS_SEED", 5)
    pts = sl.random_extended(n, seed)
    name = f"extended_{_tag()}_n{n}_seed{seed}"
    df = sl.sweep(pts, sl.out_dir() / f"{name}.parquet")
    assert len(df) == len(pts)
    _finish(df, f"random extended domain ({n} designs, seed {seed}, mesh {_tag()})", name, stress_report)
    assert (df["status"] == "invalid_geometry").sum() == sum(not sl.valid(p) for p in pts)


def test_invariance_sample(stress_report):
    """dE within 0.5 % under ds0 x0.25 / x4 and tol / 10; bitwise-identical repeated run."""
    n = sl.env_int("SNAPJUMP_STRESS_INVARIANCE_N", 12)
    seed = sl.env_int("SNAPJUMP_STRESS_SEED", 5)
    d = sl.out_dir() / f"invariance_{_tag()}_n{n}_seed{seed}"
    if d.exists():  # a fresh study each time: the bitwise repeat must compare runs of the same code
        import shutil

        shutil.rmtree(d)
    d.mkdir()
    base = SolverSettings()
    # candidates: the named designs B, C, D and 2n valid paper-grid designs; the sample is the
    # named ones plus the first n grid designs that solve ok (a failed base has nothing to compare)
    cand = sl.invariance_candidates(2 * n, seed)
    cand_df = sl.sweep(cand, d / "candidates.parquet", solver=base)
    assert not sl.check_rows(cand_df)
    ok = set(cand_df.loc[cand_df["status"] == "ok", "index"].astype(int))
    pts = [p for i, p in enumerate(cand) if i < 3 or i in ok][: 3 + n]
    base_df = sl.sweep(pts, d / "base.parquet", solver=base)
    again_df = sl.sweep(pts, d / "base_again.parquet", solver=base)
    problems = [f"not deterministic: {b}" for b in sl.compare_bitwise(base_df, again_df)]
    lines = [f"### invariance (designs B, C, D + {len(pts) - 3} paper-grid designs that solve ok, of {2 * n} "
             f"candidates; mesh {_tag()})", "",
             f"base: " + ", ".join(f"{k} {v}" for k, v in base_df["status"].value_counts().items()), "",
             "| variant | designs compared (ok) | max dE change | violations |", "|---|---|---|---|"]
    for label, solver in sl.variant_solvers(base).items():
        vdf = sl.sweep(pts, d / f"{label.replace(' ', '_').replace('/', 'div')}.parquet", solver=solver)
        bad, recs = sl.compare_dE(base_df, vdf, label)
        rels = [r["rel"] for r in recs if r["rel"] is not None]
        lines.append(f"| {label} | {len(rels)} | {100 * max(rels, default=0):.3f}% | {len(bad)} |")
        problems += bad
    lines.append(f"| repeat (bitwise) | {len(pts)} | – | {sum(p.startswith('not det') for p in problems)} |")
    text = "\n".join(lines + [""] + [f"* {p}" for p in problems])
    (d / "summary.md").write_text(text + "\n")
    stress_report(text)
    assert not problems, "\n".join(problems)
