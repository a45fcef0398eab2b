"""Numba kernels of snapjump (imported as ``snapjump_kernels``): arrays in, arrays out.

Modules: ``gent`` (energy density and its first/second derivatives in the axisymmetric
deformation-gradient components), ``elements`` (Q4/Q9 shape functions and quadrature),
``assembly`` (element loops filling a CSR pattern), ``cavity`` (exact cavity volume with its
gradient and Hessian), ``banded`` (band LDL^T with the border), ``corrector`` (the Newton
corrector in one call), ``harmonics`` (the Fourier-harmonic tangents); the multi-harmonic solid of a
followed branch (JIT-compiled only): ``mh_basis`` (the Fourier layout, phi rule and gradients),
``mh_material`` (the 3D Gent law), ``mh_element`` (energy, residual and tangent of the elements),
``mh_cavity`` (the exact 3D cavity volume); ``band_layout`` (the envelope of a sparsity pattern,
plain numpy); ``calls`` (the kernels as the solver calls them) and ``aot`` (their ahead-of-time
build).

Every kernel is ``@njit(cache=True)``. numba keys a cached function on its own source file only,
so a kernel that calls into another file (the corrector calls the assembly) would keep stale
machine code after that other file changed. :func:`_drop_stale_cache` therefore clears this
package's numba cache whenever any kernel source changed (a hash of all of them, kept next to the
cache); it runs once, at import, before any kernel is loaded.
"""
from __future__ import annotations

import hashlib
from pathlib import Path


def source_hash() -> str:
    """Hash of every kernel source file: it keys the numba cache below and the ahead-of-time
    build (:mod:`snapjump_kernels.aot`)."""
    digest = hashlib.sha256()
    for src in sorted(Path(__file__).resolve().parent.glob("*.py")):
        digest.update(src.name.encode())
        digest.update(src.read_bytes())
    return digest.hexdigest()


def _drop_stale_cache() -> None:
    cache = Path(__file__).resolve().parent / "__pycache__"
    try:
        stamp = cache / "kernels.sha256"
        current = source_hash()
        if stamp.is_file() and stamp.read_text().strip() == current:
            return
        cache.mkdir(exist_ok=True)
        for f in list(cache.glob("*.nbi")) + list(cache.glob("*.nbc")):
            f.unlink(missing_ok=True)
        stamp.write_text(current + "\n")
    except OSError:  # a read-only install: numba then uses its own cache location
        pass


_drop_stale_cache()
