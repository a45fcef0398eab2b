"""Where each harmonic's amplitudes sit in a multi-harmonic model's nodal array ``(nn, nc)``:
``a, b`` of harmonic 0, then ``a, b, c`` of each further harmonic in the order of ``hn``."""
from __future__ import annotations

__all__ = ["component_index"]


def component_index(k: int, comp: int) -> int:
    """Column of harmonic index ``k`` (0-based in ``hn``) and component ``comp`` (0 a, 1 b, 2 c)
    in the nodal amplitude array ``(nn, nc)``."""
    if k == 0:
        if comp > 1:
            raise ValueError("harmonic 0 has no c (torsion) amplitude")
        return comp
    return 2 + 3 * (k - 1) + comp
