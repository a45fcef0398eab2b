"""The finite-element solve of one scene (docs/physics.md sections 3-5), one module per stage:
:mod:`.model` (mesh + materials -> the problem interface), :mod:`.continuation` (arc-length
continuation over it; :mod:`.path` its settings and path points, :mod:`.tracer` the corrector and
tangents, :mod:`.hermite` the cubic between path points), :mod:`.snap` (the stop criterion and
the snap states), :mod:`.lower_state` (with :mod:`.descent`, its fallback), :mod:`.metrics`,
:mod:`.harmonics` (the Fourier-harmonic stability check), :mod:`.multiharmonic` and
:mod:`.follow` (the followed non-axisymmetric branch), :mod:`.fluid` and :mod:`.air_snap`
(inflating with air) and :mod:`.solve` (mesh -> model -> trace -> lower state -> metrics, within
the design's CPU-time limit of :mod:`.limits`);
:mod:`.precompile` builds the kernels ahead of time with the signatures a solve uses."""
