"""The energy descent at fixed volume started in coarser models (docs/harmonics.md, section 10.9).

In the multi-harmonic model with every harmonic ``0..N`` the energy descent from a snap's upper
state (:func:`snapjump_cli.fe.axisym.descent.descend_at_volume`) spends hundreds of iterations
walking a long valley of the energy to the lower state. The same valley exists with fewer
harmonics, where an iteration is several times cheaper (the dofs and the band both grow with the
harmonics). :func:`descend_coarse_to_fine` walks it there first: the upper state and its mode,
restricted to the harmonics ``0..4``, descend in that model; the state it comes to rest on, lifted,
starts the descent in the model itself, which then only settles the higher harmonics. A landing
that has lost the harmonics breaking the upper state's symmetry (the coarse model fell back into
that state's subspace, which the model's own descent never leaves) is not taken: the model's own
descent is made instead. The state returned is a stable equilibrium of the model itself
at the upper state's volume (the last descent is that model's own); a coarse descent that fails
falls back on the descent in the model alone.
"""
from __future__ import annotations

import logging

import numpy as np

from snapjump_cli.fe.axisym.descent import UNCONVERGED, descend_at_volume
from snapjump_cli.fe.branch.model import MultiHarmonicModel, component_index, transfer
from snapjump_cli.fe.continuation import PathPoint, Tracer

log = logging.getLogger(__name__)

__all__ = ["COARSE_HARMONICS", "OWN_AFTER_UNCONVERGED", "coarse_models", "descend_coarse_to_fine"]

#: The highest harmonics of the coarser models a descent starts in (each below the model's own):
#: ``0..4`` for the models of a secondary branch (``0..8``). A start with ``0..2`` did not pay in
#: scratch measurements (not reproducible from the repository): in the ``0..4`` model the descent
#: from the ``0..2`` model's state took 318 iterations against 330 from the upper state
#: (``follow_strata`` row 0), and ``0..8`` from ``0..2`` took 166 against 78 from ``0..4``
#: (``follow_strata_n2`` row 16, before the second class of mirror planes was checked).
COARSE_HARMONICS = (4,)


#: Where the descent in a coarser model runs out of iterations, the model's own descent from the same
#: start is made all the same (``False``: it is not, and :func:`descend_coarse_to_fine` finds
#: nothing; its callers then trace the branch, as the reference does). The coarse model walks the
#: same valley at several times less an iteration: on grid row 3030 of
#: ``configs/paper_grid_followed.yaml`` (the landing of a subcritical secondary bifurcation, started
#: 0.2 scaled arc lengths along its mode) the descent with harmonics ``0..4`` stopped after 2,000
#: iterations with the volume error still 0.13 (scaled), and the one with ``0..8`` did the same, 2/3
#: of the design's ~300 CPU-s, before the branch was traced to its landing (``bench.profile.follow
#: --sample configs/paper_grid_followed.yaml --rows 3030 --debug snapjump_cli.fe.axisym.descent``,
#: with ``--set snapjump_cli.fe.branch.coarse.OWN_AFTER_UNCONVERGED=True``).
OWN_AFTER_UNCONVERGED = False


def coarse_models(mh: MultiHarmonicModel) -> list[MultiHarmonicModel]:
    """The coarser models of ``mh`` (harmonics ``0..m`` for each ``m`` of :data:`COARSE_HARMONICS`
    below its highest harmonic; the same mesh, body and gauge): none unless ``mh`` keeps every
    harmonic ``0..N`` with ``N >= 3`` and has no imperfection."""
    hn = [int(n) for n in mh.hn]
    N = hn[-1]
    if hn != list(range(N + 1)) or N < 3 or np.any(mh.A_imp):
        return []
    return [MultiHarmonicModel(mh.base, list(range(m + 1)), free_body=mh.free_body, gauge=mh.gauge)
            for m in COARSE_HARMONICS if m < N]


def _restricted(mh: MultiHarmonicModel, small: MultiHarmonicModel, pt: PathPoint) -> PathPoint:
    """``pt`` (a state of ``mh``) with its state and tangent restricted to ``small``'s harmonics; its
    measures (the volume the descent holds) are ``mh``'s."""
    return PathPoint(transfer(mh, small, pt.u, strict=False), pt.p, pt.zeta, pt.tangent,
                     transfer(mh, small, pt.du_ds, strict=False), pt.dp_ds, 0.0)


def descend_coarse_to_fine(tracer: Tracer, upper: PathPoint) -> tuple[PathPoint | None, str]:
    """The stable state reached from ``upper`` at its volume by energy descent in the model of
    ``tracer`` (a :class:`MultiHarmonicModel`), started in its :func:`coarse_models` (see the
    module). Returns ``(state or None, message)`` as :func:`descend_at_volume` does, whose descent
    in the model alone it falls back on."""
    mh = tracer.pb
    models = coarse_models(mh) if isinstance(mh, MultiHarmonicModel) else []
    prev, prev_model, iters = None, None, []
    for small in models:
        up = _restricted(mh, small, upper)
        first = None
        if prev is not None:
            first = PathPoint(transfer(prev_model, small, prev.u), prev.p, up.zeta, up.tangent, up.du_ds, 0.0, 0.0)
        low, msg = descend_at_volume(Tracer(small, tracer.cfg), up, start=first)
        small.release_buffers()
        if low is None and msg.startswith(UNCONVERGED) and not OWN_AFTER_UNCONVERGED:
            # the same walk, several times dearer an iteration: not made (the caller traces the branch)
            log.debug("descent with harmonics 0-%d: %s; not repeated in the model itself", int(small.hn[-1]), msg)
            return None, f"with harmonics 0-{int(small.hn[-1])}: {msg}"
        if low is None:
            log.debug("descent with harmonics 0-%d: %s; the model's own descent instead", int(small.hn[-1]), msg)
            return descend_at_volume(tracer, upper)
        prev, prev_model = low, small
        iters.append(f"0-{int(small.hn[-1])}: {low.newton}")
    if prev is None:
        return descend_at_volume(tracer, upper)
    first = PathPoint(transfer(prev_model, mh, prev.u), prev.p, upper.zeta, upper.tangent, upper.du_ds, 0.0, 0.0)
    low, msg = descend_at_volume(tracer, upper, start=first)
    if low is None or not _breaks_symmetry(mh, upper.u, low.u):
        log.debug("descent from the coarser models' state: %s; the model's own descent instead",
                  msg if low is None else "it fell back into the upper state's symmetry")
        return descend_at_volume(tracer, upper)
    return low, f"{msg} (started from the descents with harmonics {', '.join(iters)} iterations)"


#: :func:`descend_coarse_to_fine`: a harmonic is absent from a state below this fraction of the
#: state's largest amplitude; a landing holds it above ``BROKEN`` of its own largest amplitude.
ABSENT, BROKEN = 1e-12, 1e-3


def _breaks_symmetry(mh: MultiHarmonicModel, u_up: np.ndarray, u: np.ndarray) -> bool:
    """Whether ``u`` holds the harmonics that the upper state ``u_up`` lacks (the ones its mode
    breaks the symmetry with), if it lacks any. A coarse model can lose the symmetry-breaking part
    (a mode with harmonics above its own, or a descent that falls back into the upper state's
    subspace, which the model's own descent then never leaves): such a landing is not taken."""
    A_up, A = np.abs(mh.amplitudes(u_up)), np.abs(mh.amplitudes(u))
    big_up, big = float(A_up.max()), float(A.max())
    absent = []
    for k, n in enumerate(mh.hn):
        o, w = component_index(k, 0), (2 if int(n) == 0 else 3)
        if float(A_up[:, o:o + w].max()) <= ABSENT * big_up:
            absent.append(float(A[:, o:o + w].max()))
    return not absent or max(absent) > BROKEN * big
