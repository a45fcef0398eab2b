"""Running jump simulations one at a time or many at once (:func:`snapjump_cli.jump.jump_heights`).

A simulation (:func:`snapjump_cli.jump._simulate`) is a generator: its flight scans ask for the
flight's ``(y_i, v_i)`` on a piece of the time grid (:data:`snapjump_cli.jump.events.Request`)
and go on with the answer, which is sent back. :func:`run_one` answers each request at once;
:func:`run_many` advances many simulations in step and answers all their pending requests
together, a few numpy calls for a block of flights instead of some thirty per flight (most of
the time of a scan on short time grids went into calling numpy). The answers are the same
numbers either way (the formulas are element-wise), so are the results.
"""
from __future__ import annotations

import gc
from typing import Any, Generator, Iterable, Sequence

import numpy as np

from snapjump_cli.jump.closed_form import FlightAt, Oscillator, Phase, flight_state
from snapjump_cli.jump.events import Request, Samples

__all__ = ["run_one", "run_many", "sample_flights"]

#: Most samples (rows x padded columns) answered by one block of :func:`sample_flights`: enough
#: to spread numpy's cost per call over many samples, few enough for the cache.
_BLOCK = 1 << 15

#: Most simulations running at once in :func:`run_many`.
_WIDTH = 1024

Simulation = Generator[Request, Samples, Any]


def run_one(sim: Simulation) -> Any:
    """Run one simulation to its end, answering each request with :meth:`PhaseModel.flight`;
    returns the simulation's value."""
    try:
        at, t = next(sim)
        while True:
            at, t = sim.send(at.md.flight(at.ph, t)[:2])
    except StopIteration as stop:
        return stop.value


def run_many(sims: Iterable[Simulation], width: int | None = None) -> list[Any]:
    """Run the simulations in step, answering the pending requests of all of them together
    (:func:`sample_flights`).

    At most ``width`` (default ``_WIDTH``) run at once, the next one starting as one ends: the
    memory stays bounded however many there are.

    Returns
    -------
    list
        Per simulation, in order, its value or the exception it raised (the others go on).
    """
    width = width or _WIDTH
    queue = enumerate(sims)
    out: list[Any] = []
    running: dict[int, Simulation] = {}
    waiting: list[tuple[int, Request]] = []

    def advance(i: int, answer: Samples | None) -> None:
        try:
            waiting.append((i, running[i].send(answer)))
            return
        except StopIteration as stop:
            out[i] = stop.value
        except Exception as e:  # noqa: BLE001 - one failing design never stops the others
            out[i] = e
        del running[i]

    def fill() -> None:
        for i, sim in queue:
            out.append(None)
            running[i] = sim
            advance(i, None)
            if len(running) >= width:
                return

    # Many suspended simulations are alive at once: the cyclic garbage collector, run every
    # few hundred allocations, would walk them all again and again (a tenth to a fifth of the
    # time on the paper grid). Nothing here needs it: reference counting frees the simulations'
    # objects, and the few cycles (scipy's brentq makes one per call) wait for the next pass.
    collecting = gc.isenabled()
    gc.disable()
    try:
        fill()
        while waiting:
            batch, waiting = waiting, []
            for (i, _), answer in zip(batch, sample_flights([req for _, req in batch])):
                advance(i, answer)
            fill()
    finally:
        if collecting:
            gc.enable()
    return out


def sample_flights(requests: Sequence[Request]) -> list[Samples]:
    """``(y_i, v_i)`` for each request ``(at, t)``, the same numbers as ``at.md.flight(at.ph, t)``.

    The requests of under-damped flights (every real design) are answered in blocks of
    similar length: their constants stacked as columns, their times as the rows of a 2-D array
    (padded with their last time), and :func:`snapjump_cli.jump.events.flight_state` evaluated once
    per block. Any other request is answered alone.
    """
    answers: list[Samples | None] = [None] * len(requests)
    stack = []
    for j, (at, t) in enumerate(requests):
        if isinstance(at, FlightAt) and not at.general and t.size:
            stack.append(j)
        else:
            answers[j] = at.md.flight(at.ph, t)[:2]
    stack.sort(key=lambda j: requests[j][1].size)
    start = 0
    while start < len(stack):
        width = requests[stack[start]][1].size
        stop = start + 1
        # rows of about the same length: a block grows while its padded size stays small
        while stop < len(stack) and (stop - start + 1) * requests[stack[stop]][1].size <= max(_BLOCK, width):
            stop += 1
        block = stack[start:stop]
        for j, yv in zip(block, _sample_block([requests[j] for j in block])):
            answers[j] = yv
        start = stop
    return answers  # type: ignore[return-value]


def _sample_block(requests: Sequence[Request]) -> list[Samples]:
    """One evaluation of :func:`flight_state` for under-damped flights stacked row by row."""
    ats = [at for at, _ in requests]
    n = max(t.size for _, t in requests)
    T = np.empty((len(requests), n))
    for row, (_, t) in zip(T, requests):
        row[:t.size] = t
        row[t.size:] = t[-1]

    def col(values: Iterable[float]) -> np.ndarray:
        return np.fromiter(values, float, len(ats))[:, None]

    ph = Phase("flight", 0.0, 0.0, col(a.ph.y0 for a in ats), col(a.ph.v0 for a in ats),
                col(a.ph.e0 for a in ats), col(a.ph.ed0 for a in ats))
    Y, V, _, _ = flight_state(col(a.md.r for a in ats), col(a.md.g for a in ats),
                         Oscillator.stacked([a.md.rel for a in ats]), ph, T)
    return [(Y[i, :t.size], V[i, :t.size]) for i, (_, t) in enumerate(requests)]
