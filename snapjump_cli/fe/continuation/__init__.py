"""Arc-length continuation over a small problem interface; knows no mesh (pacopy-like).

:mod:`.path` (the interface ``Problem``, the settings, path points and paths), :mod:`.tracer`
(the Riks corrector and the tangents), :mod:`.stepping` (the step control and :func:`trace`),
:mod:`.hermite` (the cubic between two path points). The names a caller needs are here:
``from snapjump_cli.fe.continuation import trace, Tracer, PathPoint``.
"""
from snapjump_cli.fe.continuation.path import ContinuationFailed, ContinuationSettings, Path, PathPoint, Problem
from snapjump_cli.fe.continuation.stepping import trace
from snapjump_cli.fe.continuation.tracer import Tracer, point_between, start_point

__all__ = ["trace", "Tracer", "Path", "PathPoint", "ContinuationSettings", "ContinuationFailed", "start_point",
           "point_between", "Problem"]
