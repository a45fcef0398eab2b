"""The followed / axisymmetric CPU ratios of ``bench.profile.follow --json`` runs, summarised.

    .venv/bin/python -m bench.profile.follow --sample bench/harmonics_sample/follow_strata.yaml --rows 0 1 ... 23 --json bench/out/follow_strata.json
    .venv/bin/python -m bench.profile.follow --sample bench/harmonics_sample/follow_strata_n2.yaml --rows 0 1 ... 23 --json bench/out/follow_strata_n2.json
    .venv/bin/python -m bench.profile.ratios bench/out/follow_strata.json bench/out/follow_strata_n2.json

prints, for each file and for all of them together, the number of followed designs, the median
and the 90th percentile (numpy's linear interpolation) of the followed CPU over the warm
axisymmetric solve and check, the largest, and the designs at or above ``--limit`` CPU-s (the
sweep's default per-design limit, 300 s): the figures of issue 36's aims (10x, 50x, none at the
limit).
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def summary(rows: list[dict], limit: float) -> dict:
    """Count, median, 90th percentile and largest ratio of the followed rows of ``rows``, and the
    designs at or above ``limit`` CPU-s."""
    r = [row for row in rows if row.get("ratio") is not None]
    ratios = np.array([float(row["ratio"]) for row in r])
    slow = [row["design"] for row in r if float(row.get("cpu_followed_s") or 0.0) >= limit]
    if not len(ratios):
        return {"designs": 0, "at_limit": slow}
    return {"designs": len(ratios), "median": float(np.median(ratios)), "p90": float(np.percentile(ratios, 90)),
            "largest": float(ratios.max()), "at_limit": slow}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.profile.ratios", description=__doc__.split("\n\n")[0])
    ap.add_argument("files", nargs="+", type=Path, help="--json outputs of bench.profile.follow")
    ap.add_argument("--limit", type=float, default=300.0, help="per-design CPU-s limit to count designs at (default 300)")
    a = ap.parse_args(argv)
    groups = {str(f): json.loads(f.read_text()) for f in a.files}
    if len(groups) > 1:
        groups["all"] = [row for rows in list(groups.values()) for row in rows]
    print("| runs | followed designs | median | 90th percentile | largest | at the limit |\n|---|---|---|---|---|---|")
    for name, rows in groups.items():
        s = summary(rows, a.limit)
        if not s["designs"]:
            print(f"| {name} | 0 | | | | |")
            continue
        print(f"| {name} | {s['designs']} | {s['median']:.1f}x | {s['p90']:.1f}x | {s['largest']:.0f}x | "
              f"{len(s['at_limit'])} {' '.join(s['at_limit'])} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
