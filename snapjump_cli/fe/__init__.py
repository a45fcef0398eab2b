"""The finite-element solve of one scene (docs/physics.md sections 3-5), one subpackage per stage;
imports go one way, down this list:

* :mod:`.continuation` -- arc-length continuation over a problem interface (knows no mesh);
* :mod:`.axisym` -- the axisymmetric model, the snap, its lower state and metrics, air;
* :mod:`.stability` -- the Fourier-harmonic check, the margins, the eigenvalue helpers;
* :mod:`.branch` -- the followed non-axisymmetric branch, its secondary bifurcations, imperfections;
* :mod:`.solve` -- the one orchestrator: mesh -> model -> trace -> lower state -> metrics, the
  mesh check, the harmonic check, margins and the followed branch, within the design's CPU-time
  limit of :mod:`.limits` (a leaf every stage may use);

:mod:`.precompile` builds the kernels ahead of time with the signatures a solve uses. The row
keys the stages fill are declared in :mod:`snapjump_cli.schema`."""
