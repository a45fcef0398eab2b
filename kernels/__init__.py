"""Numba kernels of snapjump (imported as ``snapjump_kernels``): arrays in, arrays out.

Modules: ``gent`` (energy density and its first/second derivatives in the axisymmetric
deformation-gradient components), ``elements`` (Q4/Q9 shape functions and quadrature),
``assembly`` (element loops filling a CSR pattern), ``cavity`` (exact cavity volume with its
gradient and Hessian).
"""
