"""The search of ``snapjump optimize``: the normalised box, multi-start pattern (compass) search
with a quadratic-model step, and differential evolution (see :mod:`snapjump_cli.optimize.run`)."""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

import numpy as np
import pandas as pd

from snapjump_cli.optimize.evaluate import Evaluation, Evaluator, objective_values
from snapjump_cli.optimize.spec import COLUMNS, IMPROVE_REL, PARAMETERS, OptimizeSpec

log = logging.getLogger("snapjump_cli.optimize.run")


class Box:
    """The map between the normalised box of the free parameters and the five parameters."""

    def __init__(self, bounds: Mapping[str, tuple[float, float]]) -> None:
        self.bounds = dict(bounds)
        self.free = [p for p in PARAMETERS if bounds[p][0] < bounds[p][1]]
        self.d = len(self.free)

    def to_params(self, u: Sequence[float]) -> tuple[float, ...]:
        vals = {p: self.bounds[p][0] for p in PARAMETERS}
        for p, x in zip(self.free, u):
            lo, hi = self.bounds[p]
            vals[p] = lo + float(np.clip(x, 0.0, 1.0)) * (hi - lo)
        return tuple(vals[p] for p in PARAMETERS)

    def to_unit(self, params: Sequence[float]) -> np.ndarray:
        vals = dict(zip(PARAMETERS, params))
        return np.array([(vals[p] - self.bounds[p][0]) / (self.bounds[p][1] - self.bounds[p][0]) for p in self.free])

    def contains(self, params: Sequence[float], rtol: float = 1e-9) -> bool:
        for p, x in zip(PARAMETERS, params):
            lo, hi = self.bounds[p]
            tol = rtol * max(1.0, abs(lo), abs(hi))
            if not (lo - tol <= x <= hi + tol):
                return False
        return True


@dataclass
class _Local:
    """One running compass search."""

    ident: int
    x: np.ndarray
    f: float
    h: float
    e: Evaluation
    prev: np.ndarray | None = None
    path: list[Evaluation] = field(default_factory=list)
    done: bool = False
    merged: bool = False
    phase: str = "poll"         # poll -> (failed, h <= model_step) cross -> model -> poll
    last_poll: dict[str, tuple[float, float]] = field(default_factory=dict)
    last_h: float = math.nan


def candidates_from(df: pd.DataFrame, box: Box, spec: OptimizeSpec) -> tuple[list[tuple[float, ...]], float, tuple | None]:
    """Start points from a result table: its feasible rows inside the box, best first; and the
    best y_jump_m of those rows (the baseline) with its design."""
    scored = objective_values(df, spec.objective, spec.jump)
    params = scored[list(COLUMNS.values())].to_numpy(dtype=float)
    inside = np.array([box.contains(p) for p in params], dtype=bool) if len(params) else np.zeros(0, bool)
    feas = inside & np.isfinite(scored["_f"].to_numpy(dtype=float))
    sc = scored[feas].assign(_p=list(map(tuple, params[feas])))
    sc = sc.sort_values("_f", ascending=False, kind="stable")
    baseline, base_design = math.nan, None
    if len(sc):
        yj = sc["y_jump_m"].to_numpy(dtype=float)
        j = int(np.nanargmax(yj))
        baseline, base_design = float(yj[j]), tuple(float(x) for x in sc["_p"].iloc[j])
    return [tuple(float(x) for x in p) for p in sc["_p"]], baseline, base_design


def _spread_ok(u: np.ndarray, taken: Sequence[np.ndarray], spread: float) -> bool:
    return all(float(np.linalg.norm(u - v)) >= spread for v in taken)


def _initial_sample(box: Box, n: int, seed: int) -> list[tuple[float, ...]]:
    """The box centre and a seeded Latin hypercube of ``n - 1`` points (one point per stratum
    ``[k/m, (k+1)/m)`` of every free parameter, strata paired at random)."""
    pts = [box.to_params([0.5] * box.d)]
    m = n - 1
    if m > 0:
        rng = np.random.default_rng(seed)
        u = np.empty((m, box.d))
        for j in range(box.d):
            u[:, j] = (rng.permutation(m) + rng.random(m)) / m
        pts += [box.to_params(row) for row in u]
    return pts


def _poll_directions(box: Box, poll: str, rng: np.random.Generator) -> list[tuple[str, np.ndarray]]:
    """The 2 d poll directions: ``+-`` the unit vectors, or ``+-`` the columns of the Householder
    matrix ``I - 2 v v^T`` of a random unit vector ``v`` (an orthonormal basis; OrthoMADS-style)."""
    d = box.d
    basis = np.eye(d)
    names = list(box.free)
    if poll == "rotating":
        v = rng.standard_normal(d)
        v /= np.linalg.norm(v)
        basis = np.eye(d) - 2.0 * np.outer(v, v)
        names = [f"dir{k}" for k in range(d)]
    out = []
    for k in range(d):
        for sgn, tag in ((-1.0, "-"), (1.0, "+")):
            out.append((names[k] + tag, sgn * basis[:, k]))
    return out


def _quadratic_terms(S: np.ndarray) -> np.ndarray:
    n, d = S.shape
    cols = [np.ones(n)] + [S[:, i] for i in range(d)]
    cols += [S[:, i] * S[:, j] for i in range(d) for j in range(i, d)]
    return np.column_stack(cols)


def _cross_points(box: Box, lc: _Local) -> list[tuple[str, np.ndarray]]:
    """``x + h (e_i + e_j)``, ``i < j`` (inside the box: a coordinate that would leave it steps back)."""
    out = []
    for i in range(box.d):
        for j in range(i + 1, box.d):
            v = np.zeros(box.d)
            for k in (i, j):
                v[k] = 1.0 if lc.x[k] + lc.h <= 1.0 + 1e-12 else -1.0
            out.append((f"{box.free[i]}+{box.free[j]}", np.clip(lc.x + lc.h * v, 0.0, 1.0)))
    return out


def _model_point(ev: Evaluator, box: Box, lc: _Local, rng: np.random.Generator, trust: float = 2.0
                 ) -> np.ndarray | None:
    """The maximiser, within ``trust`` poll steps of the incumbent and inside the box, of the
    quadratic fitted (least squares) to the feasible evaluations within one poll step of it (the
    poll and cross points: the full quadratic is determined); ``None`` when fewer points than
    terms are feasible or the model promises no improvement."""
    d = box.d
    n_terms = 1 + d + d * (d + 1) // 2
    feas = [e for e in ev.evals if math.isfinite(e.f)]
    if len(feas) < n_terms:
        return None
    S = (np.array([box.to_unit(e.params) for e in feas]) - lc.x) / lc.h
    near = np.max(np.abs(S), axis=1) <= 1.0 + 1e-6
    if int(near.sum()) < n_terms:
        return None
    scale = abs(lc.f) if lc.f != 0 else 1.0
    A = _quadratic_terms(S[near])
    b = (np.array([e.f for e in feas])[near] - lc.f) / scale
    coef, *_ = np.linalg.lstsq(A, b, rcond=None)
    g = coef[1:1 + d]
    H = np.zeros((d, d))
    k = 1 + d
    for i in range(d):
        for j in range(i, d):
            H[i, j] += coef[k] if i != j else 2.0 * coef[k]
            if i != j:
                H[j, i] += coef[k]
            k += 1
    lo = np.maximum((0.0 - lc.x) / lc.h, -trust)
    hi = np.minimum((1.0 - lc.x) / lc.h, trust)
    # the best of a seeded sample of the trust box, polished by projected gradient ascent
    cand = lo + (hi - lo) * rng.random((4096, d))
    pred = _quadratic_terms(cand) @ coef
    z = cand[int(np.argmax(pred))]
    step = 1.0 / max(float(np.max(np.abs(np.linalg.eigvalsh(H)))), 1e-12)
    for _ in range(200):
        z = np.clip(z + step * (g + H @ z), lo, hi)
    m = float((_quadratic_terms(z[None, :]) @ coef)[0])
    if not m > 2 * IMPROVE_REL:
        return None
    y = np.clip(lc.x + lc.h * z, 0.0, 1.0)
    return None if np.max(np.abs(y - lc.x)) < 1e-9 else y


@dataclass
class _Starts:
    """The start points not yet taken (best first) and the local searches running and finished."""

    queue: list[tuple[float, ...]]
    running: list[_Local] = field(default_factory=list)
    finished: list[_Local] = field(default_factory=list)
    n_ident: int = 0


def _initial_queue(ev: Evaluator, box: Box, spec: OptimizeSpec, cands: list[tuple[float, ...]],
                   iteration: int) -> list[tuple[float, ...]]:
    """The start points: ``cands``, or (no usable ``--from`` rows) the feasible designs of an
    initial sample, best first."""
    if cands:
        return list(cands)
    n_init = spec.search.init or 2 * box.d + 1
    init = ev.ask([(p, "init") for p in _initial_sample(box, n_init, spec.seed)], iteration)
    feas = [e for e in init if e is not None and math.isfinite(e.f)]
    return [e.params for e in sorted(feas, key=lambda e: (-e.f, e.number))]


def _take_starts(ev: Evaluator, box: Box, spec: OptimizeSpec, st: _Starts, iteration: int) -> None:
    """Start local searches from the queue (each ``spread`` away from the others) until ``starts``
    run, the queue is empty or the budget is spent."""
    s = spec.search
    while len(st.running) < s.starts and st.queue and ev.remaining > 0:
        want = s.starts - len(st.running)
        taken = [lc.x for lc in st.running + st.finished]
        picked, rest = [], []
        for p in st.queue:
            u = box.to_unit(p)
            if len(picked) < want and _spread_ok(u, taken + [box.to_unit(q) for q in picked], s.spread):
                picked.append(p)
            else:
                rest.append(p)
        if not picked:
            return
        st.queue = rest
        got = ev.ask([(p, "start") for p in picked], iteration)
        for p, e in zip(picked, got):
            if e is None or not math.isfinite(e.f):
                continue
            st.running.append(_Local(ident=st.n_ident, x=box.to_unit(e.params), f=e.f, h=s.step, e=e, path=[e]))
            st.n_ident += 1


def _requests(ev: Evaluator, box: Box, spec: OptimizeSpec, running: list[_Local], iteration: int
              ) -> tuple[list[tuple[tuple[float, ...], str]], list[tuple[_Local, str, np.ndarray]]]:
    """The designs of one iteration, best start first: per start its cross points, its model point,
    or its pattern point and poll; with the owner (start, tag, normalised point) of each."""
    requests: list[tuple[tuple[float, ...], str]] = []
    owners: list[tuple[_Local, str, np.ndarray]] = []
    for lc in sorted(running, key=lambda lc: (-lc.f, lc.ident)):
        if lc.phase == "cross":
            for name, y in _cross_points(box, lc):
                requests.append((box.to_params(y), "cross"))
                owners.append((lc, name, y))
            continue
        if lc.phase == "model":
            y = _model_point(ev, box, lc, np.random.default_rng([spec.seed, iteration, lc.ident]))
            if y is not None:
                requests.append((box.to_params(y), "model"))
                owners.append((lc, "model", y))
            continue
        if lc.prev is not None:  # pattern point after a successful move
            y = np.clip(lc.x + (lc.x - lc.prev), 0.0, 1.0)
            if not np.allclose(y, lc.x):
                requests.append((box.to_params(y), "pattern"))
                owners.append((lc, "pattern", y))
        dirs = _poll_directions(box, spec.search.poll, np.random.default_rng([spec.seed, iteration, lc.ident]))
        for name, v in dirs:
            y = np.clip(lc.x + lc.h * v, 0.0, 1.0)
            if np.allclose(y, lc.x):
                continue
            requests.append((box.to_params(y), "poll"))
            owners.append((lc, name, y))
    return requests, owners


def _update_local(lc: _Local, mine: list[tuple[str, np.ndarray, Evaluation | None]], box: Box,
                  spec: OptimizeSpec) -> None:
    """Move ``lc`` to its best improving point, else advance its phase (poll -> cross -> model ->
    poll with ``h`` halved; done when ``h < min_step``); unchanged if the budget cut its batch."""
    s = spec.search
    best = None
    for tag, y, e in mine:
        if e is not None and math.isfinite(e.f) and e.f > lc.f + IMPROVE_REL * abs(lc.f) \
                and (best is None or e.f > best[2].f):
            best = (tag, y, e)
    if best is not None:
        lc.prev, lc.x, lc.f, lc.e = lc.x, best[1], best[2].f, best[2]
        lc.path.append(best[2])
        lc.last_poll, lc.last_h = {}, math.nan
        lc.phase = "poll"
        return
    if any(e is None for _, _, e in mine):
        return
    if lc.phase == "poll":
        # a complete poll around the incumbent, none better: the local sensitivities
        lc.last_poll = {tag: e.f for tag, y, e in mine if tag != "pattern"}
        lc.last_h = lc.h
        lc.prev = None
    if lc.phase == "poll" and s.model and lc.h <= s.model_step * (1 + 1e-9) and box.d > 1:
        lc.phase = "cross"
    elif lc.phase == "cross":
        lc.phase = "model"
    else:
        lc.phase = "poll"
        lc.h /= 2.0
        if lc.h < s.min_step:
            lc.done = True


def _merge_and_retire(st: _Starts) -> None:
    """Stop the worse of two starts that met, and move the stopped starts to ``finished``."""
    for lc in sorted(st.running, key=lambda lc: (-lc.f, lc.ident)):
        if lc.done:
            continue
        for other in st.running:
            if other is lc or other.done or (other.f, -other.ident) < (lc.f, -lc.ident):
                continue
            if float(np.max(np.abs(other.x - lc.x))) < 0.5 * lc.h:
                lc.done = lc.merged = True
                log.info("start %d met start %d; it stops", lc.ident, other.ident)
                break
    for lc in [lc for lc in st.running if lc.done]:
        st.running.remove(lc)
        st.finished.append(lc)
        if not lc.merged:
            log.info("start %d converged at f = %.6g (h = %.3g)", lc.ident, lc.f, lc.h)


def pattern_search(ev: Evaluator, box: Box, spec: OptimizeSpec, cands: list[tuple[float, ...]]) -> dict[str, Any]:
    """Multi-start compass search (method ``pattern``; see :mod:`snapjump_cli.optimize.run`): the
    polls of all running starts form one batch per iteration."""
    iteration = 0
    st = _Starts(queue=_initial_queue(ev, box, spec, cands, iteration))
    _take_starts(ev, box, spec, st, iteration)
    while st.running and ev.remaining > 0:
        iteration += 1
        requests, owners = _requests(ev, box, spec, st.running, iteration)
        got = ev.ask(requests, iteration)
        truncated = any(e is None for e in got)
        for lc in list(st.running):
            _update_local(lc, [(tag, y, e) for (o, tag, y), e in zip(owners, got) if o is lc], box, spec)
        _merge_and_retire(st)
        b = ev.best()
        log.info("iteration %d: %d solves of %d, %d starts running, best %.6g", iteration, ev.n_solves,
                 ev.budget, len(st.running), b.f if b is not None else math.nan)
        if truncated:
            break
        _take_starts(ev, box, spec, st, iteration)
    return {"locals": st.finished + st.running, "iterations": iteration}


def differential_evolution(ev: Evaluator, box: Box, spec: OptimizeSpec, cands: list[tuple[float, ...]]) -> dict[str, Any]:
    from scipy.optimize import differential_evolution

    pop = spec.search.popsize * box.d
    maxiter = max(0, spec.budget // pop - 1)
    gen = {"n": 0}

    def mapper(func: Callable, xs: Any) -> list[float]:
        xs = list(xs)
        got = ev.ask([(box.to_params(x), "de") for x in xs], gen["n"])
        gen["n"] += 1
        return [(-e.f if e is not None and math.isfinite(e.f) else 0.0) for e in got]

    x0 = box.to_unit(cands[0]) if cands else None
    differential_evolution(lambda x: 0.0, [(0.0, 1.0)] * box.d, maxiter=maxiter, popsize=spec.search.popsize,
                           rng=np.random.default_rng(spec.seed), polish=False, init="latinhypercube",
                           updating="deferred", workers=mapper, tol=0.0, atol=0.0, x0=x0)
    return {"locals": [], "iterations": gen["n"]}

