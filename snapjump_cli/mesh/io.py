"""Mesh files: a :class:`~snapjump_cli.mesh.data.Mesh` written as ``.msh`` (gmsh 4.1) or ``.vtu`` (VTK XML, written with meshio).

Both keep the mesh's node numbering and element order; ``.msh`` has one physical group per region
and per edge set, ``.vtu`` the cell data ``region`` and ``material``.

The frame of every 3D file snapjump writes (``.vtu`` here, the ParaView series of ``curve
--export``, the STEP, BREP and STL solids of :mod:`snapjump_cli.mesh.solids`) is one
(:data:`FRAME`): **millimetres, the symmetry axis along z (up), the ground at z = 0** (a design's
ring bottom, a single cap's base plane or its ring's bottom), the meridian section ``phi = 0`` in
the plane ``y = 0`` (``x = r``). So the files overlay in ParaView. The ``.msh`` file is the
solver's own 2D mesh, in metres ``(r, y)`` as the solver sees it.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from snapjump_cli.mesh.gmsh_session import LINE_TYPES, QUAD_TYPES, gmsh_session
from snapjump_cli.mesh.data import REGION_NAMES, Mesh

__all__ = ["MESH_SUFFIXES", "write_mesh", "FRAME", "ground_level", "to_frame"]

#: File formats :func:`write_mesh` understands.
MESH_SUFFIXES = (".msh", ".vtu")
#: The 3D files' frame, stated in their headers.
FRAME = "unit: mm; axis z (up); ground z = 0"
_MM = 1e3


def ground_level(mesh: Mesh) -> float:
    """The ground's height in the mesh's coordinates [m]: the lowest node of the ``ground`` node set
    (a ring's bottom face), else of ``base`` (a single cap's base plane), else of the mesh."""
    for name in ("ground", "base"):
        nodes = mesh.node_sets.get(name)
        if nodes is not None and len(nodes):
            return float(np.asarray(mesh.nodes)[np.asarray(nodes, int), 1].min())
    return float(np.asarray(mesh.nodes)[:, 1].min())


def to_frame(points_rz: np.ndarray, y_ground: float, phi: np.ndarray | float = 0.0) -> np.ndarray:
    """Section points ``(r, y)`` [m] (n, 2) -> 3D points in :data:`FRAME` (n, 3) [mm]:
    ``(r cos phi, r sin phi, y - y_ground)``."""
    P = np.asarray(points_rz, float)
    c, s = np.cos(phi), np.sin(phi)
    return np.column_stack([P[:, 0] * c, P[:, 0] * s + 0.0 * P[:, 0], P[:, 1] - y_ground]) * _MM


def write_mesh(mesh: Mesh, path: str | os.PathLike) -> Path:
    """Write ``mesh`` to ``path``: ``.msh`` (gmsh 4.1, physical groups per region and edge set)
    or ``.vtu`` (VTK XML, cell data ``region`` / ``material``). Written atomically
    (:func:`snapjump_cli.files.write_atomic`), so a failed write leaves nothing behind. Returns the path."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise ValueError(f"mesh file must end in {' or '.join(MESH_SUFFIXES)}, got {str(path)!r}")
    from snapjump_cli.files import write_atomic

    return write_atomic(path, lambda tmp: (_write_msh if suffix == ".msh" else _write_vtu)(mesh, tmp))


def _write_msh(mesh: Mesh, path: Path) -> None:
    n = mesh.n_nodes
    with gmsh_session("snapjump_out") as gmsh:
        m = gmsh.model
        tags = np.arange(1, n + 1)
        xyz = np.column_stack([mesh.nodes, np.zeros(n)]).ravel()
        base = m.addDiscreteEntity(2)
        m.mesh.addNodes(2, base, tags.tolist(), xyz.tolist())
        qtype, ltype = QUAD_TYPES[mesh.order], LINE_TYPES[mesh.order]
        next_tag = 1
        first = True
        for reg in sorted(set(mesh.region.tolist())):
            sel = mesh.elements[mesh.region == reg]
            ent = base if first else m.addDiscreteEntity(2)
            first = False
            etags = np.arange(next_tag, next_tag + sel.shape[0])
            next_tag += sel.shape[0]
            m.mesh.addElementsByType(ent, qtype, etags.tolist(), (sel + 1).ravel().tolist())
            pg = m.addPhysicalGroup(2, [ent])
            m.setPhysicalName(2, pg, REGION_NAMES.get(reg, f"region{reg}"))
        for name, edges in sorted(mesh.edge_sets.items()):
            if edges.size == 0:
                continue
            ent = m.addDiscreteEntity(1)
            etags = np.arange(next_tag, next_tag + edges.shape[0])
            next_tag += edges.shape[0]
            m.mesh.addElementsByType(ent, ltype, etags.tolist(), (edges + 1).ravel().tolist())
            pg = m.addPhysicalGroup(1, [ent])
            m.setPhysicalName(1, pg, name)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.option.setNumber("Mesh.Binary", 0)
        gmsh.write(str(path))


def _write_vtu(mesh: Mesh, path: Path) -> None:
    """VTK XML (binary, compressed) with meshio: ``quad`` / ``quad9`` cells (VTK_QUAD,
    VTK_BIQUADRATIC_QUAD; the node order is gmsh's), cell data ``region`` and ``material``; the
    section in the plane ``y = 0`` of :data:`FRAME` (mm, z up, ground at 0)."""
    import meshio  # a dependency; imported here, since most runs never write a mesh

    cell = {1: "quad", 2: "quad9"}[mesh.order]
    pts = to_frame(mesh.nodes, ground_level(mesh))
    meshio.Mesh(pts, [(cell, np.asarray(mesh.elements, np.int64))],
                cell_data={"region": [np.asarray(mesh.region, np.int32)],
                           "material": [np.asarray(mesh.material, np.int32)]}).write(path, file_format="vtu")
