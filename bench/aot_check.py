"""The bench sample solved with the ahead-of-time compiled kernels and with the JIT-compiled ones:
every reported value must be the same bits.

    .venv/bin/python -m bench.aot_check [-j 2]

Runs ``bench.regression compare`` twice (``SNAPJUMP_NO_AOT=0`` and ``=1``, the 257 rows of the
seeded paper-grid sample, the named designs and the Fig. 1 caps), then compares every value of
every row but the timings. Exit 1 if any differs. (docs/performance.md, "Start-up".)
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _rows(path: Path) -> dict[str, dict]:
    doc = json.loads(path.read_text())
    return {r["id"]: r for r in (doc["rows"] if isinstance(doc, dict) else doc)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-j", "--jobs", type=int, default=2)
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        out = {}
        for mode, flag in (("aot", "0"), ("jit", "1")):
            out[mode] = Path(tmp) / f"{mode}.json"
            subprocess.run([sys.executable, "-m", "bench.regression", "compare", "-j", str(a.jobs), "--out", str(out[mode])],
                           cwd=REPO, env=dict(os.environ, SNAPJUMP_NO_AOT=flag), check=True, stdout=subprocess.DEVNULL)
        aot, jit = _rows(out["aot"]), _rows(out["jit"])
    n = differ = 0
    for rid, row in aot.items():
        for k, v in row.items():
            if k.endswith("_s"):
                continue
            w = jit[rid].get(k)
            n += 1
            same = v == w or (isinstance(v, float) and isinstance(w, float) and math.isnan(v) and math.isnan(w))
            if not same:
                differ += 1
                print(f"{rid} {k}: aot {v!r}, jit {w!r}")
    print(f"{n} values in {len(aot)} rows compared: {differ} differ")
    return 1 if differ or set(aot) != set(jit) else 0


if __name__ == "__main__":
    raise SystemExit(main())
