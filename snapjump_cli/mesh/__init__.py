"""Meshes of the scenes: :mod:`.build` (gmsh builds the structured mesh of a design or a cap:
``mesh_scene``) with its in-process :mod:`.gmsh_session`, :mod:`.tidy` (boundary chains, node
order and orientation after gmsh), :mod:`.io` (``.msh`` / ``.vtu`` files) and :mod:`.data` (the
``Mesh`` arrays handed to the solver, their measures and the node ordering). gmsh is imported
only when a mesh is built or written. The names of :mod:`.build` are re-exported here."""
from __future__ import annotations

from snapjump_cli.mesh.build import (
    MESH_SUFFIXES,
    SNAP_FRAC,
    SNAP_TOL,
    mesh_scene,
    meshed_design,
    solid_volumes,
    write_mesh,
)

__all__ = ["mesh_scene", "meshed_design", "SNAP_TOL", "SNAP_FRAC", "write_mesh", "MESH_SUFFIXES", "solid_volumes"]
