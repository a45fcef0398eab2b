"""References, errors, convergence verdicts and the choice of the default mesh setting.

Reference of a case (per metric): the order-2 runs at the reference aspect ratio, sorted by nt.
With the three finest levels that succeeded, ``f_k = f_0 + C h_k^p`` (``h = 1/nt``) is solved for
``f_0`` and ``p`` (Richardson extrapolation with the observed order); it is used when the three
values are monotone and ``p`` lies in [0.5, 8]. Otherwise the reference is the finest level
(``finest``), and with fewer than three levels too.

A case *converges* (and takes part in the choice of the default) when, for both dE and dy_pole,
either the reference is a Richardson extrapolation whose distance to the finest level (the finest
level's estimated error) is at most ``CONV_EST`` (2 % for dE, 1 % for dy_pole), or the two finest
levels agree within ``CONV_PAIR`` (0.25 % / 0.1 %). Cases that snap on some meshes and not on others,
fail on the finest ones, or do not satisfy the above are *mesh-sensitive* and excluded (listed).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable

from scipy.optimize import brentq

METRICS = ("dE_J", "dy_pole_m")
#: Error thresholds of the default: dE <= 1 %, dy_pole <= 0.5 %.
THRESH = {"dE_J": 0.01, "dy_pole_m": 0.005}
CONV_EST = {"dE_J": 0.02, "dy_pole_m": 0.01}
CONV_PAIR = {"dE_J": 0.0025, "dy_pole_m": 0.001}
P_RANGE = (0.5, 8.0)


def setting_key(order: int, nt: int, aspect: float) -> tuple[int, int, float]:
    return (int(order), int(nt), float(aspect))


def setting_label(s: tuple[int, int, float]) -> str:
    return f"Q{'4' if s[0] == 1 else '9'} nt={s[1]} a={s[2]:g}"


def richardson(nts: list[int], f: list[float]) -> tuple[float, str, float | None]:
    """Extrapolate three values on meshes ``h = 1/nt`` (ascending nt) to ``h -> 0``.

    Returns ``(f_0, method, p)``: ``method`` is ``richardson`` or why not (``finest: ...``).
    """
    if len(f) < 3:
        return f[-1], f"finest ({len(f)} level{'s' if len(f) != 1 else ''})", None
    (h1, h2, h3), (f1, f2, f3) = [1.0 / n for n in nts[-3:]], f[-3:]
    d1, d2 = f1 - f2, f2 - f3
    if d2 == 0.0:
        return f3, "finest (converged to round-off)", None
    if d1 * d2 <= 0.0:
        return f3, "finest (not monotone)", None
    ratio = d1 / d2

    def g(p: float) -> float:
        return (h1**p - h2**p) / (h2**p - h3**p) - ratio

    lo, hi = P_RANGE
    if g(lo) * g(hi) > 0:
        return f3, "finest (observed order out of range)", None
    p = brentq(g, lo, hi, xtol=1e-10)
    C = d2 / (h2**p - h3**p)
    return f3 - C * h3**p, "richardson", p


@dataclass
class Reference:
    value: float | None
    method: str
    p: float | None = None
    est_err: float | None = None  # |ref - finest| / |ref|
    pair_diff: float | None = None  # |finest - second finest| / |finest|
    levels: list[int] = field(default_factory=list)


@dataclass
class CaseVerdict:
    case: str
    converges: bool
    reason: str
    refs: dict[str, Reference]


def _rel(a: float, b: float) -> float:
    return abs(a - b) / max(abs(b), 1e-300)


def case_reference(runs: list[dict], ref_aspect: float) -> CaseVerdict:
    """Reference values and the convergence verdict of one case from its runs."""
    case = runs[0]["case"] if runs else "?"
    o2 = sorted([r for r in runs if r["order"] == 2 and r["aspect"] == ref_aspect and r["status"] in
                 ("ok", "no_snap", "failed", "error", "timeout")], key=lambda r: r["nt"])
    solved = [r for r in o2 if r["status"] in ("ok", "no_snap")]
    refs: dict[str, Reference] = {}
    if not solved:
        return CaseVerdict(case, False, "no order-2 run succeeded", {m: Reference(None, "none") for m in METRICS})
    statuses = {r["status"] for r in solved}
    if statuses == {"no_snap"}:
        return CaseVerdict(case, False, "does not snap on any order-2 mesh",
                           {m: Reference(0.0, "no snap") for m in METRICS})
    # failures above the finest successful level make the finest trend unknown
    failed_fine = [r["nt"] for r in o2 if r["status"] in ("failed", "error") and r["nt"] >= solved[-1]["nt"]]
    ok = [r for r in solved if r["status"] == "ok"]
    reasons = []
    if "no_snap" in statuses:
        reasons.append("snaps on nt=" + ",".join(str(r["nt"]) for r in ok) + " but not on nt="
                       + ",".join(str(r["nt"]) for r in solved if r["status"] == "no_snap"))
    if failed_fine:
        reasons.append("fails on the finest order-2 mesh(es) nt=" + ",".join(map(str, failed_fine)))
    for m in METRICS:
        vals = [(r["nt"], r["metrics"].get(m)) for r in ok if r["metrics"].get(m) is not None]
        if not vals:
            refs[m] = Reference(None, "none")
            continue
        nts, f = [v[0] for v in vals], [float(v[1]) for v in vals]
        val, method, p = richardson(nts, f)
        ref = Reference(val, method, p, levels=nts[-3:])
        ref.est_err = _rel(f[-1], val) if val and method == "richardson" else None
        ref.pair_diff = _rel(f[-2], f[-1]) if len(f) >= 2 else None
        refs[m] = ref
    conv = not reasons
    if conv:
        for m in METRICS:
            r = refs[m]
            if r.value is None:
                conv = False
                reasons.append(f"no {m} value")
                continue
            good_rich = r.method == "richardson" and r.est_err is not None and r.est_err <= CONV_EST[m]
            good_pair = r.pair_diff is not None and r.pair_diff <= CONV_PAIR[m]
            if not (good_rich or good_pair):
                conv = False
                pd = f"{100 * r.pair_diff:.2f}%" if r.pair_diff is not None else "n/a"
                ee = f"{100 * r.est_err:.2f}%" if r.est_err is not None else "n/a"
                reasons.append(f"{m}: {r.method}, finest-level estimated error {ee}, two finest differ by {pd}")
    if len(ok) < 2 and conv:
        conv, reasons = False, reasons + ["fewer than two successful order-2 levels"]
    return CaseVerdict(case, conv, "; ".join(reasons) if reasons else "converges", refs)


def run_errors(run: dict, verdict: CaseVerdict) -> dict[str, float | None]:
    """Relative errors of a run against its case's reference (inf when the run did not give a value
    where the reference has one, None when there is no reference)."""
    out: dict[str, float | None] = {}
    for m in METRICS:
        ref = verdict.refs.get(m)
        if ref is None or ref.value is None:
            out[m] = None
            continue
        if run["status"] not in ("ok", "no_snap"):
            out[m] = math.inf
            continue
        v = run["metrics"].get(m)
        if run["status"] == "no_snap":
            v = 0.0
        if v is None:
            out[m] = math.inf
        elif ref.value == 0.0:
            out[m] = 0.0 if v == 0.0 else math.inf
        else:
            out[m] = _rel(float(v), ref.value)
    return out


@dataclass
class SettingSummary:
    setting: tuple[int, int, float]
    n_cases: int  # converged cases with a run at this setting
    n_missing: int  # converged cases without a run (skipped: budget / not requested)
    max_err: dict[str, float]
    total_wall: float
    median_wall: float
    passes: bool
    failing: list[str]


def summarize_settings(runs: Iterable[dict], verdicts: dict[str, CaseVerdict]) -> list[SettingSummary]:
    """Per mesh setting: worst errors over the converged cases and total time; ``passes`` when every
    converged case ran and met :data:`THRESH`."""
    import statistics

    runs = list(runs)
    conv = [c for c, v in verdicts.items() if v.converges]
    settings = sorted({setting_key(r["order"], r["nt"], r["aspect"]) for r in runs})
    out = []
    for s in settings:
        rs = {r["case"]: r for r in runs if setting_key(r["order"], r["nt"], r["aspect"]) == s}
        max_err = {m: 0.0 for m in METRICS}
        walls, failing, missing = [], [], 0
        for c in conv:
            r = rs.get(c)
            if r is None or r["status"] == "skipped":
                missing += 1
                continue
            e = run_errors(r, verdicts[c])
            bad = False
            for m in METRICS:
                if e[m] is None:
                    continue
                max_err[m] = max(max_err[m], e[m])
                bad |= e[m] > THRESH[m]
            if bad:
                failing.append(c + (f" ({r['status']})" if r["status"] not in ("ok", "no_snap") else ""))
            if r.get("wall_s") is not None:
                walls.append(r["wall_s"])
            else:
                walls.append(math.inf)
        n = len(conv) - missing
        out.append(SettingSummary(s, n, missing, max_err, sum(walls), statistics.median(walls) if walls else math.nan,
                                  passes=bool(conv) and missing == 0 and not failing, failing=failing))
    return out


def choose_default(summaries: list[SettingSummary]) -> SettingSummary | None:
    """The cheapest (total wall time over the converged cases) setting that passes."""
    ok = [s for s in summaries if s.passes]
    return min(ok, key=lambda s: s.total_wall) if ok else None


def pareto(points: list[tuple[float, float, object]]) -> list[object]:
    """Labels of the points (time, error, label) on the lower-left Pareto front, by increasing time."""
    front, best = [], math.inf
    for t, e, lab in sorted(points, key=lambda x: (x[0], x[1])):
        if e < best:
            front.append(lab)
            best = e
    return front
