"""The kernels as the solver calls them: compiled ahead of time when built for these sources
(:mod:`snapjump_kernels.aot`), the ``@njit`` dispatchers otherwise; the multi-harmonic kernels
(:data:`JIT_KERNELS`, a followed branch's) are always JIT-compiled, their module imported when one
is first called. Importing this module imports numba only when there is no matching
ahead-of-time build. The library takes every kernel from here."""
from __future__ import annotations

from snapjump_kernels.aot import active, kernel, lazy_jit
from snapjump_kernels.band_layout import band_of_maps, envelope_extents
from snapjump_kernels.elements import element_tables, quadrature_geometry

#: kernel module -> the kernels the solver calls from Python (what the ahead-of-time build exports)
KERNELS: dict[str, tuple[str, ...]] = {
    "assembly": ("assemble", "evaluate", "pressure_mass_inverse", "quadrature_jacobians", "reference_geometry"),
    "banded": ("band_ldlt", "band_ldlt_solve", "bordered_factor", "bordered_solve", "sym_band_matvec"),
    "cavity": ("cavity_assemble", "cavity_volume"),
    "corrector": ("newton_correct",),
    "harmonics": ("harmonic_band", "harmonic_cavity_matrices", "harmonic_element_parts", "scatter_band"),
}

#: kernel module -> the kernels called from Python that are never compiled ahead of time (the
#: multi-harmonic model's: a followed branch; their module is imported, with numba, on first call)
JIT_KERNELS: dict[str, tuple[str, ...]] = {
    "banded": ("band_ldlt_into", "bordered_factor_into", "bordered_factor_upto"),
    "mh_basis": ("phi_rule", "point_gradients"),
    "mh_element": ("mh_elements", "mh_assemble_band", "scatter_vector"),
    "mh_cavity": ("mh_cavity",),
    "mh_mirror": ("mirror_elements", "mirror_cavity"),
}

# each name of KERNELS, as the solver calls it (``from snapjump_kernels.calls import evaluate``)
globals().update({name: kernel(module, name) for module, names in KERNELS.items() for name in names})
globals().update({name: lazy_jit(module, name) for module, names in JIT_KERNELS.items() for name in names})

#: whether the ahead-of-time compiled kernels are in use in this process
AOT: bool = active()

__all__ = ["KERNELS", "JIT_KERNELS", "AOT", "band_of_maps", "envelope_extents", "element_tables", "quadrature_geometry",
           *(name for names in KERNELS.values() for name in names),
           *(name for names in JIT_KERNELS.values() for name in names)]
