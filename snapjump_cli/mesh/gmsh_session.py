"""The in-process gmsh session shared by the mesh builder (:mod:`snapjump_cli.mesh.build`) and the
``.msh`` writer (:mod:`snapjump_cli.mesh.io`), and gmsh's element type codes."""
from __future__ import annotations

import contextlib
from collections.abc import Iterator
from types import ModuleType

__all__ = ["gmsh_session", "QUAD_TYPES", "LINE_TYPES"]

#: gmsh element types of the quadrangles per mesh order: 4-node and 9-node.
QUAD_TYPES = {1: 3, 2: 10}
#: gmsh element types of the boundary lines per mesh order: 2-node and 3-node (start, end, mid).
LINE_TYPES = {1: 1, 2: 8}


@contextlib.contextmanager
def gmsh_session(model_name: str = "snapjump") -> Iterator[ModuleType]:
    """Initialise gmsh quietly (no GUI, no config files, no signal handler), yield the module and
    always finalise it, even on error. If gmsh was already initialised by the caller, a fresh model
    is added and removed instead of finalising."""
    import gmsh

    owner = not gmsh.isInitialized()
    if owner:
        saved = _python_signal_handlers()
        gmsh.initialize(readConfigFiles=False, interruptible=False)
        # gmsh's C++ initialisation resets SIGINT/SIGTERM to their defaults behind Python's back
        # (the sweep's clean stop on SIGTERM was lost: the process died, its workers ran on)
        _reinstall(saved)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.Verbosity", 0)
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.model.add(model_name)
        yield gmsh
    finally:
        if owner:
            gmsh.finalize()
        else:  # pragma: no cover - only when embedded in a caller's gmsh session
            with contextlib.suppress(Exception):
                gmsh.model.remove()


def _python_signal_handlers() -> dict:
    """Python's handlers of SIGINT and SIGTERM (empty off the main thread, where they cannot be set)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return {}
    return {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM) if signal.getsignal(sig) is not None}


def _reinstall(handlers: dict) -> None:
    import signal

    for sig, h in handlers.items():
        signal.signal(sig, h)
