"""The followed answers of two ``bench.profile.follow --json`` runs of the same designs, compared
(e.g. the sweep's mesh against one finer: the mesh convergence of the followed answers).

    .venv/bin/python -m bench.profile.answers bench/out/follow_strata.json bench/out/follow_strata_nt3.json

prints, per design followed in both runs, the relative difference of each answer the jump takes
(dE, dy_pole, V*, p*; relative to the second run's) and whether both landed the same way (the
follow kind and how the lower state was found), then the median and the largest difference of
each answer over the designs that landed the same way and over all.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

#: The answers compared (the four the jump model takes; ``bench.profile.follow --compare`` reports them too).
ANSWER_KEYS = ("dE_J", "dy_pole_m", "V_star_m3", "p_star_Pa")


def _how(row: dict) -> str:
    """How a design's snap was found: its follow kind and how its branch's lower state was found."""
    lower = [b.get("lower_note") or "" for b in row.get("branches", [])[:1]]
    how = lower[0].split(":")[0] if lower else ""
    return f"{row.get('follow_kind')} / {how}"


def compare(a: list[dict], b: list[dict]) -> list[dict]:
    """Per design followed in both runs (matched by position in the design list, the label's
    ``#row``): the relative differences of :data:`ANSWER_KEYS` and whether both landed the same way."""
    def key(r: dict) -> str:
        return r["design"].rsplit("#", 1)[-1]

    fine = {key(r): r for r in b if r.get("dE_J") is not None}
    out = []
    for r in a:
        s = fine.get(key(r))
        if r.get("dE_J") is None or s is None:
            continue
        d = {k: abs(r[k] - s[k]) / max(abs(s[k]), 1e-300) for k in ANSWER_KEYS if r.get(k) is not None and s.get(k) is not None}
        out.append({"design": key(r), "same_way": _how(r) == _how(s), "how": _how(r), "how_other": _how(s), **d})
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.profile.answers", description=__doc__.split("\n\n")[0])
    ap.add_argument("first", type=Path, help="--json output of bench.profile.follow")
    ap.add_argument("second", type=Path, help="--json output of the same designs (the reference: e.g. one mesh finer)")
    a = ap.parse_args(argv)
    rows = compare(json.loads(a.first.read_text()), json.loads(a.second.read_text()))
    print("| row | " + " | ".join(ANSWER_KEYS) + " | landed the same way |\n|---|" + "---|" * (len(ANSWER_KEYS) + 1))
    for r in rows:
        print(f"| {r['design']} | " + " | ".join(f"{r.get(k, float('nan')):.2g}" for k in ANSWER_KEYS)
              + f" | {'yes' if r['same_way'] else 'no: ' + r['how'] + ' vs ' + r['how_other']} |")
    for name, sel in (("landed the same way", [r for r in rows if r["same_way"]]), ("all", rows)):
        if not sel:
            continue
        stats = ", ".join(f"{k} median {np.median([r[k] for r in sel]):.2g} largest {max(r[k] for r in sel):.2g}"
                          for k in ANSWER_KEYS)
        print(f"\n{name} ({len(sel)} designs): {stats}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
