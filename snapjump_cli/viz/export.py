"""The traced path as a ParaView time series: ``snapjump curve ... --export FILE.pvd|FILE.xdmf``.

One time step per state of :func:`snapjump_cli.viz.states.path_steps` (time = the step number,
the ``step`` column of ``--csv``; each step carries its volume and pressure, below), on the
reference mesh in the frame of every 3D file snapjump writes
(:data:`snapjump_cli.mesh.io.FRAME`: **millimetres, z up, the ground at z = 0**, the section
``phi = 0`` in the plane ``y = 0``; the STEP/STL solids of ``snapjump mesh`` overlay it), written
with meshio:

* point data ``displacement_mm`` (3 components, millimetres: ParaView's "Warp By Vector" with
  scale 1 shows the state) and ``max_principal_stretch`` (the largest principal stretch of the
  deformation gradient, ``lambda_max``);
* cell data ``rubber_mean_stress_Pa`` (the rubber's mean stress ``kappa (theta - 1)``, the mixed
  element's pressure field at the element centre, positive in tension: not the cavity pressure),
  ``region`` (0 inner cap, 1 ring, 2 outer cap) and ``material`` (0 inner rubber, 1 outer rubber);
* per step: ``p_Pa`` (the cavity pressure), ``V_m3`` (the curve's volume), ``arc_length``,
  ``on_path`` and ``state`` (0 none, 1 start, 2 the pressure maximum, 3 the upper state, 4 the
  lower state, 5 the bifurcation: :data:`STATE_CODES`).

``.pvd``: a ParaView collection of one VTU file per step (binary, compressed) in the folder
``<stem>_steps/`` beside it; the per-step values are each VTU's field data, and the collection
names the named states. ``.xdmf``: one XDMF 3 file, the data inline (ASCII; no HDF5 needed);
the per-step values are ``Information`` elements of each step's grid, and the collection's
``Information`` named ``states`` lists the named states' steps.

``revolve=N`` writes the solid of revolution instead of the section: the section (a Q9 split
into its four Q4) swept about the axis in ``N`` sectors, hexahedra and, on the axis, wedges; 3D
coordinates ``(r cos phi, r sin phi, z)``.

A followed solve (``--harmonics N --follow``) is written by :func:`export_actuator`: the states the
actuator takes (:func:`snapjump_cli.viz.actuator.actuator_path`: the axisymmetric loading to the
bifurcation, the followed branch to its snap, the lower state), always as a solid of revolution
whose every point moves with the Fourier series of its section (``u_r e_r + u_phi e_phi + u_z
e_z`` at its angle), so ParaView shows the tilted, partly inverted states; ``max_principal_stretch``
is that of the full 3D deformation gradient at each point's angle; per step also ``jump`` (1: the
state is reached by a jump at fixed volume: the snap) and ``branch`` (0 axisymmetric, 1 followed).
"""
from __future__ import annotations

import logging
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["EXPORT_SUFFIXES", "STATE_CODES", "export_steps", "export_actuator", "revolve_section", "steps_folder",
           "FOLLOWED_SECTORS", "FIELD_NAMES"]

log = logging.getLogger(__name__)

#: File formats :func:`export_steps` writes.
EXPORT_SUFFIXES = (".pvd", ".xdmf")
#: The ``state`` code of each step (field data / Information ``state``).
STATE_CODES = {"": 0, "start": 1, "p_max": 2, "upper": 3, "lower": 4, "bifurcation": 5}
#: Sectors of a followed solve's 3D export when ``--revolve`` is not given.
FOLLOWED_SECTORS = 48
#: The exported fields: name -> what it is.
FIELD_NAMES = {
    "displacement_mm": "point data: displacement [mm] (3 components, the frame's x, y, z)",
    "max_principal_stretch": "point data: the largest principal stretch of the deformation gradient",
    "rubber_mean_stress_Pa": "cell data: the rubber's mean stress kappa (theta - 1) [Pa], positive in tension "
                             "(the mixed element's pressure field; not the cavity pressure)",
    "region": "cell data: 0 inner cap, 1 ring, 2 outer cap",
    "material": "cell data: 0 inner rubber, 1 outer rubber",
}
_BRANCH_CODES = {"axisymmetric": 0, "followed": 1, "imperfect": 2}

_VTK_CELL = {1: "quad", 2: "quad9"}
_Q9_SPLIT = np.array([[0, 4, 8, 7], [4, 1, 5, 8], [8, 5, 2, 6], [7, 8, 6, 3]])


def steps_folder(path: str | Path) -> Path:
    """The folder of the VTU files of a ``.pvd`` collection: ``<stem>_steps`` beside it."""
    path = Path(path)
    return path.with_name(f"{path.stem}_steps")


@dataclass
class _Geometry:
    """The exported mesh: points (n, 3), cell blocks, the map from its points to the section's
    nodes with their angle, and the parent element of every cell."""

    points: np.ndarray
    cells: list[tuple[str, np.ndarray]]
    node: np.ndarray  # (n,) section node of each point
    phi: np.ndarray  # (n,) its angle
    parent: list[np.ndarray]  # per cell block: the section element of each cell


def _frame_section(mesh) -> np.ndarray:
    """The section's nodes in the frame's units and origin: ``(r, height above the ground)`` [mm]."""
    from snapjump_cli.mesh.io import ground_level

    P = np.asarray(mesh.nodes, float).copy()
    P[:, 1] -= ground_level(mesh)
    return P * 1e3


def _section(mesh) -> _Geometry:
    from snapjump_cli.mesh.io import ground_level, to_frame

    n = mesh.n_nodes
    pts = to_frame(mesh.nodes, ground_level(mesh))
    return _Geometry(pts, [(_VTK_CELL[mesh.order], np.asarray(mesh.elements, np.int64))], np.arange(n),
                     np.zeros(n), [np.arange(mesh.n_elements)])


def revolve_section(nodes: np.ndarray, elements: np.ndarray, order: int, sectors: int,
                    axis_tol: float | None = None) -> _Geometry:
    """The solid of revolution of a section in ``sectors`` sectors (see the module docstring):
    points ``(r cos phi, r sin phi, z)``.

    Parameters
    ----------
    nodes : (n, 2) section nodes ``(r, z)``
    elements : (ne, nen) quadrilaterals (gmsh order; a Q9 is split into its four Q4)
    order : 1 or 2
    sectors : number of sectors (>= 3) around the axis
    axis_tol : distance from the axis below which a node lies on it (default 1e-9 of the size)
    """
    if sectors < 3:
        raise ValueError(f"revolve needs at least 3 sectors, got {sectors}")
    nodes = np.asarray(nodes, float)
    quads = np.asarray(elements)[:, _Q9_SPLIT].reshape(-1, 4) if order == 2 else np.asarray(elements)
    parent = np.repeat(np.arange(len(elements)), 4 if order == 2 else 1)
    used = np.unique(quads)
    tol = axis_tol if axis_tol is not None else 1e-9 * float(np.abs(nodes).max())
    on_axis = np.abs(nodes[:, 0]) <= tol
    # point ids: one per axis node, one per (off-axis node, sector)
    ids = -np.ones((len(nodes), sectors), np.int64)
    pts, node, phi = [], [], []
    angles = 2.0 * np.pi * np.arange(sectors) / sectors
    k = 0
    for v in used:
        if on_axis[v]:
            ids[v, :] = k
            pts.append((0.0, 0.0, nodes[v, 1]))
            node.append(v)
            phi.append(0.0)
            k += 1
    off = used[~on_axis[used]]
    for j, a in enumerate(angles):
        ids[off, j] = np.arange(k, k + len(off))
        r = nodes[off, 0]
        pts += list(zip(r * np.cos(a), r * np.sin(a), nodes[off, 1]))
        node += off.tolist()
        phi += [a] * len(off)
        k += len(off)
    hexes, wedges, hex_parent, wedge_parent = [], [], [], []
    for q, e in zip(quads, parent):
        axis = on_axis[q]
        for j in range(sectors):
            lo, hi = ids[q, j], ids[q, (j + 1) % sectors]
            if not axis.any():
                hexes.append(np.r_[hi, lo])  # (r, phi, z) right-handed: positive volumes
                hex_parent.append(e)
            elif axis.sum() == 2:
                # the quad's edge on the axis stays put: a wedge between the two swept nodes' arcs,
                # each axis node paired with its off-axis neighbour
                p0, p1 = (int(v) for v in q if on_axis[v])
                s0, s1 = (int(v) for v in q if not on_axis[v])
                if not _adjacent(q, p0, s0):
                    s0, s1 = s1, s0
                nxt = (j + 1) % sectors
                wedges.append([ids[p0, 0], ids[s0, j], ids[s0, nxt], ids[p1, 0], ids[s1, j], ids[s1, nxt]])
                wedge_parent.append(e)
            else:  # a corner on the axis only (not in the meshes of mesh_scene): a degenerate hexahedron
                hexes.append(np.r_[hi, lo])  # (r, phi, z) right-handed: positive volumes
                hex_parent.append(e)
    points = np.array(pts, float)
    cells, parents = [], []
    if hexes:
        cells.append(("hexahedron", np.array(hexes, np.int64)))
        parents.append(np.array(hex_parent, np.int64))
    if wedges:
        W = _orient_wedges(points, np.array(wedges, np.int64))
        cells.append(("wedge", W))
        parents.append(np.array(wedge_parent, np.int64))
    return _Geometry(points, cells, np.array(node, np.int64), np.array(phi, float), parents)


def _adjacent(q: np.ndarray, a: int, b: int) -> bool:
    """Whether nodes ``a`` and ``b`` are neighbours (share an edge) in the quad ``q``."""
    i, j = list(q).index(a), list(q).index(b)
    return (i - j) % 4 in (1, 3)


def _orient_wedges(points: np.ndarray, W: np.ndarray) -> np.ndarray:
    """VTK's wedge order: the triangle (0, 1, 2)'s normal (right-hand rule) points away from the
    triangle (3, 4, 5); wedges the other way round have their two triangles swapped."""
    a, b, c = points[W[:, 0]], points[W[:, 1]], points[W[:, 2]]
    nrm = np.cross(b - a, c - a)
    towards = points[W[:, 3:]].mean(axis=1) - (a + b + c) / 3.0
    flip = np.einsum("ij,ij->i", nrm, towards) > 0
    W = W.copy()
    W[flip] = W[flip][:, [3, 4, 5, 0, 1, 2]]
    return W


def _step_data(geom: _Geometry, U: np.ndarray, fields: dict, mesh) -> tuple[dict, dict]:
    """Point and cell data of one step on the exported geometry."""
    u = U[geom.node] * 1e3
    c, s = np.cos(geom.phi), np.sin(geom.phi)
    disp = np.column_stack([u[:, 0] * c, u[:, 0] * s, u[:, 1]])
    point_data = {"displacement_mm": disp,
                  "max_principal_stretch": np.asarray(fields["stretch"], float)[geom.node]}
    cell_data = {
        "rubber_mean_stress_Pa": [np.asarray(fields["element_pressure_Pa"], float)[p] for p in geom.parent],
        "region": [np.asarray(mesh.region, np.int32)[p] for p in geom.parent],
        "material": [np.asarray(mesh.material, np.int32)[p] for p in geom.parent],
    }
    return point_data, cell_data


def _scalars(steps, k: int) -> dict[str, float]:
    return {"p_Pa": float(steps.p_Pa[k]), "V_m3": float(steps.V_m3[k]), "arc_length": float(steps.arc_length[k]),
            "on_path": int(bool(steps.on_path[k])), "state": STATE_CODES[steps.state[k]]}


def _states_line(steps) -> str:
    return ", ".join(f"{name} {steps.index(name)}" for name in STATE_CODES if name and steps.index(name) is not None)


def export_steps(res, steps, path: str | Path, revolve: int = 0, stage=None) -> list[Path]:
    """Write the states of a solved scene as a ParaView time series (module docstring).

    Parameters
    ----------
    res : the :class:`~snapjump_cli.fe.solve.SceneResult` (its model gives the fields)
    steps : its :class:`~snapjump_cli.viz.states.Steps`
    path : ``.pvd`` or ``.xdmf`` file (an existing one, and a ``.pvd``'s step folder, are replaced)
    revolve : 0 for the section, else the number of sectors of the solid of revolution
    stage : a :class:`~snapjump_cli.files.AtomicFiles` to write into (its ``commit`` puts the
        files in place, with the command's other outputs); default: one of its own, committed

    Returns
    -------
    list of Path
        The files to be written (the ``.pvd`` and its folder, or the ``.xdmf``).
    """
    import meshio  # noqa: F401  (a regular dependency; imported here to keep start-up light)

    from snapjump_cli.viz.states import step_fields

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in EXPORT_SUFFIXES:
        raise ValueError(f"export file must end in {' or '.join(EXPORT_SUFFIXES)}, got {str(path)!r}")
    mesh = res.model.mesh
    geom = revolve_section(_frame_section(mesh), mesh.elements, mesh.order, revolve) if revolve else _section(mesh)
    data = [_step_data(geom, steps.U[k], step_fields(res, steps, k), mesh) for k in range(len(steps))]
    return _write_series(path, geom, steps, data, None, stage)


def _write_series(path: Path, geom: _Geometry, steps, data: list, scalars, stage) -> list[Path]:
    """The ``.pvd`` (with its step folder) or ``.xdmf`` of ``steps`` staged in ``stage`` (default:
    one of its own, committed here, or discarded if the write fails); the paths written."""
    from snapjump_cli.files import AtomicFiles

    own = stage is None
    stage = stage or AtomicFiles()
    try:
        if path.suffix.lower() == ".pvd":
            folder = steps_folder(path)
            _write_pvd(stage.file(path), stage.folder(folder), folder.name, geom, steps, data, scalars)
            out = [path, folder]
        else:
            _write_xdmf(stage.file(path), geom, steps, data, scalars)
            out = [path]
        if own:
            stage.commit()
    except BaseException:
        if own:
            stage.discard()
        raise
    return out


def _write_pvd(pvd: Path, folder: Path, folder_ref: str, geom: _Geometry, steps, data: list, scalars=None) -> None:
    """The collection file ``pvd`` (referring to its VTU files as ``folder_ref/step_*.vtu``) and the
    VTU files in ``folder``."""
    import meshio

    from snapjump_cli.files import current_umask

    width = max(4, len(str(len(steps) - 1)))
    names = []
    for k, (pdata, cdata) in enumerate(data):
        name = f"step_{k:0{width}d}.vtu"
        meshio.Mesh(geom.points, geom.cells, point_data=pdata, cell_data=cdata).write(folder / name,
                                                                                     file_format="vtu")
        _add_field_data(folder / name, {"step": k, **(scalars or _scalars)(steps, k)})
        os.chmod(folder / name, 0o666 & ~current_umask())
        names.append(name)
    root = ET.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
    from snapjump_cli.mesh.io import FRAME

    root.append(ET.Comment(f" snapjump: {FRAME}; one step per state; time = step (each step's cavity pressure p_Pa "
                           f"and volume V_m3 are its field data); named states: {_states_line(steps)} "))
    coll = ET.SubElement(root, "Collection")
    for k, name in enumerate(names):
        attrs = {"timestep": str(k), "group": "", "part": "0", "file": f"{folder_ref}/{name}"}
        if steps.state[k]:
            attrs["name"] = steps.state[k]
        ET.SubElement(coll, "DataSet", attrs)
    ET.indent(root)
    pvd.write_text(ET.tostring(root, encoding="unicode", xml_declaration=True) + "\n", encoding="utf-8")


def _add_field_data(vtu: Path, values: dict[str, float]) -> None:
    """Add ``values`` as the VTU file's field data (ParaView shows it with the step; meshio's VTU
    writer writes none, its reader reads it)."""
    tree = ET.parse(vtu)
    grid = tree.getroot().find("UnstructuredGrid")
    fd = ET.Element("FieldData")
    for key, val in values.items():
        kind = "Int64" if isinstance(val, int) else "Float64"
        arr = ET.SubElement(fd, "DataArray", type=kind, Name=key, NumberOfTuples="1", format="ascii")
        arr.text = str(val) if kind == "Int64" else repr(float(val))
    grid.insert(0, fd)
    tree.write(vtu, encoding="utf-8", xml_declaration=True)


def _write_xdmf(path: Path, geom: _Geometry, steps, data: list, scalars=None) -> None:
    from meshio.xdmf import TimeSeriesWriter

    with TimeSeriesWriter(path, data_format="XML") as w:
        w.write_points_cells(geom.points, geom.cells)
        for k, (pdata, cdata) in enumerate(data):
            w.write_data(float(k), point_data=pdata, cell_data=cdata)
        # per-step values as XDMF Information elements (meshio's reader skips them; the
        # collection holds the steps only, which meshio counts)
        from snapjump_cli.mesh.io import FRAME

        ET.SubElement(w.domain, "Information", Name="states", Value=_states_line(steps))
        ET.SubElement(w.domain, "Information", Name="frame", Value=FRAME)
        grids = [g for g in w.collection if g.tag == "Grid"]
        for k, g in enumerate(grids):
            for key, val in (scalars or _scalars)(steps, k).items():
                ET.SubElement(g, "Information", Name=key, Value=repr(val))


def _actuator_scalars(act, k: int) -> dict[str, float]:
    return {"p_Pa": float(act.p_Pa[k]), "V_m3": float(act.V_m3[k]), "arc_length": float("nan"), "on_path": 1,
            "state": STATE_CODES.get(act.state[k], 0), "jump": int(bool(act.jump[k])),
            "branch": _BRANCH_CODES.get(act.branch[k], 0)}


def _actuator_data(geom: _Geometry, act, k: int, mesh) -> tuple[dict, dict]:
    """Point and cell data of state ``k`` of a followed solve on the revolved geometry: every point
    displaced by the Fourier series at its own angle, the stretch of the 3D gradient there."""
    from snapjump_cli.viz.fields import nodal_stretch_3d

    hn, A = np.asarray(act.hn[k], float), act.A[k]
    phi = geom.phi
    ur = np.zeros(len(phi))
    uz = np.zeros(len(phi))
    uphi = np.zeros(len(phi))
    for j, n in enumerate(hn):
        o = 0 if j == 0 else 2 + 3 * (j - 1)
        ur += A[geom.node, o] * np.cos(n * phi)
        uz += A[geom.node, o + 1] * np.cos(n * phi)
        if j > 0:
            uphi += A[geom.node, o + 2] * np.sin(n * phi)
    c, s = np.cos(phi), np.sin(phi)
    disp = np.column_stack([ur * c - uphi * s, ur * s + uphi * c, uz]) * 1e3
    lam = np.empty(len(phi))
    X = np.asarray(mesh.nodes, float)
    for a in np.unique(phi):
        sel = phi == a
        lam[sel] = nodal_stretch_3d(X, A, hn, mesh.elements, mesh.order, float(a))[geom.node[sel]]
    point_data = {"displacement_mm": disp, "max_principal_stretch": lam}
    cell_data = {
        "region": [np.asarray(mesh.region, np.int32)[p] for p in geom.parent],
        "material": [np.asarray(mesh.material, np.int32)[p] for p in geom.parent],
    }
    return point_data, cell_data


def export_actuator(res, act, path: str | Path, sectors: int = FOLLOWED_SECTORS, stage=None) -> list[Path]:
    """Write the states a followed actuator takes (:class:`~snapjump_cli.viz.actuator.ActuatorPath`)
    as a ParaView time series of the solid of revolution in ``sectors`` sectors, each point moved
    by its section's Fourier series (module docstring). Arguments and answer as in
    :func:`export_steps`; no ``rubber_mean_stress_Pa`` (the multi-harmonic model's pressure field is
    not carried along the branch)."""
    import meshio  # noqa: F401

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in EXPORT_SUFFIXES:
        raise ValueError(f"export file must end in {' or '.join(EXPORT_SUFFIXES)}, got {str(path)!r}")
    mesh = res.model.mesh
    geom = revolve_section(_frame_section(mesh), mesh.elements, mesh.order, sectors)
    data = [_actuator_data(geom, act, k, mesh) for k in range(len(act))]
    return _write_series(path, geom, act, data, _actuator_scalars, stage)
