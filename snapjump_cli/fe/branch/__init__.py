"""The followed non-axisymmetric branch (docs/harmonics.md sections 10-12): :mod:`.model` (the
multi-harmonic model; :mod:`.layout` its nodal array, :mod:`.block` a diagonal block of its
tangent), :mod:`.bifurcation` (where a harmonic leaves the axisymmetric path),
:mod:`.metrics` (a branch's snap metrics and curve), :mod:`.trace` (the branch traced to its
snap), :mod:`.secondary` (its stability against the harmonics it does not keep, and the branch
that leaves it), :mod:`.followed` (the design's answer: the one module that sees both trace and
secondary) and :mod:`.imperfection` (an imperfect actuator traced to its snap).

Imported by module (``from snapjump_cli.fe.branch.followed import apply_followed``)."""
