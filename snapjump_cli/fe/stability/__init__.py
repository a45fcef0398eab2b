"""Non-axisymmetric stability of an axisymmetric path: :mod:`.harmonics` (the Fourier-harmonic
check, ``check_harmonics``), :mod:`.margins` (how far each harmonic is from losing stability) and
:mod:`.eigen` (the eigenvalue and inertia helpers they and the followed branch share).

Imported by module (``from snapjump_cli.fe.stability.harmonics import check_harmonics``)."""
