"""A diagonal block of the multi-harmonic tangent: the harmonics a branch does not keep.

At a state of a branch of ``n_c`` (its harmonics the multiples of ``n_c``) the tangent of the model
with every harmonic decouples: a harmonic ``k`` couples with ``k +- m n_c`` only, so the multiples
of ``n_c`` form one diagonal block and the other harmonics another. The branch's own model is
(the quadrature aside) the first; whether the state is stable outside the branch is a question
about the second alone, a band of about half the dofs and half the bandwidth: its element pass
forms only that block's rows (:func:`snapjump_kernels.mh_element.mh_assemble_band` with ``sel``)
and its ``LDL^T`` costs about a tenth of the whole tangent's.

:class:`HarmonicBlock` numbers the block's dofs (in the order of the model's free dofs) and holds
its band layout; :meth:`snapjump_cli.fe.branch.model.MultiHarmonicModel.block_band` assembles it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from snapjump_cli.fe.branch.layout import component_index
from snapjump_kernels.calls import band_of_maps

__all__ = ["HarmonicBlock", "harmonic_block"]


@dataclass(frozen=True)
class HarmonicBlock:
    """The dofs of some harmonics of a model and the band layout of their diagonal block.

    ``sel (K,)`` which of the model's harmonics; ``dofs (n,)`` the model's free dofs of the block,
    ascending (block dof ``i`` is ``dofs[i]``); ``edofs, ecoef, gdofs, gcoef`` the element and
    cavity-edge maps to block dofs (-1: outside the block or fixed); ``kl`` and ``ext`` the band's
    half-bandwidth and envelope."""

    sel: np.ndarray
    dofs: np.ndarray
    edofs: np.ndarray
    ecoef: np.ndarray
    gdofs: np.ndarray
    gcoef: np.ndarray
    kl: int
    ext: np.ndarray

    @property
    def n(self) -> int:
        return int(self.dofs.shape[0])


def harmonic_block(model, harmonics) -> HarmonicBlock:
    """The block of ``harmonics`` (harmonic numbers, each kept by ``model``, a
    :class:`~snapjump_cli.fe.branch.model.MultiHarmonicModel`)."""
    want = {int(n) for n in harmonics}
    missing = want - {int(n) for n in model.hn}
    if missing:
        raise ValueError(f"harmonics {sorted(missing)} are not kept ({[int(n) for n in model.hn]})")
    sel = np.array([int(n) in want for n in model.hn], dtype=np.bool_)
    cols = [component_index(k, c) for k, n in enumerate(model.hn) if sel[k] for c in range(2 if n == 0 else 3)]
    d = model.dofmap[:, cols]
    dofs = np.unique(d[d >= 0])
    to_block = -np.ones(model.n + 1, np.int64)  # (index -1 -> the last entry: stays -1)
    to_block[dofs] = np.arange(dofs.shape[0])
    edofs = np.ascontiguousarray(to_block[model.edofs])
    gdofs = np.ascontiguousarray(to_block[model.gdofs])
    kl, ext = band_of_maps((edofs, gdofs), dofs.shape[0])
    return HarmonicBlock(sel, dofs, edofs, model.ecoef, gdofs, model.gcoef, kl, ext)
