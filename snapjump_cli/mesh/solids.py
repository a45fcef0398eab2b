"""The designed actuator as 3D solids for CAD and mould making: ``snapjump mesh ... --out FILE.step``
(also ``.stp``, ``.brep``, ``.stl``), built with gmsh's OpenCASCADE kernel.

The solids are the exact geometry of eqs 1-6 (docs/physics.md section 1), as designed: a design
gives three separate solids, ``inner_cap``, ``ring`` and ``outer_cap``; a single cap gives
``inner_cap`` or ``outer_cap`` and, with ``--bc ring-roller``, its ``ring``. Each is a spherical
shell cut by its base plane (two balls and a half-space) or an annulus (two cylinders).

Units and axes: **millimetres**; the symmetry axis is ``z``, the ground (a design's ring bottom,
a single cap's base plane, or its ring bottom) is ``z = 0``: the frame of every 3D file snapjump
writes (:data:`snapjump_cli.mesh.io.FRAME`; the ``.vtu`` mesh and the ``curve --export`` series
overlay these solids in ParaView). The STEP and STL headers name the solids with their exact volumes so that
they add up visibly: ``inner_cap + ring = inner solid`` (the jump model's ``m_i``, what ``snapjump
mesh`` reports as ``V inner solid``) and ``outer_cap = outer solid`` (``m_o``).

* STEP: an assembly ``snapjump_<name>`` of one part per solid, named as above; the file's
  description says ``unit: mm`` and the length unit is ``SI_UNIT(.MILLI.,.METRE.)``.
* BREP (OpenCASCADE's format, no units or names of its own): the solids in the order above, after
  a first line ``# snapjump ...; unit: mm; solids: ...``.
* STL (ASCII): one ``solid NAME`` block per solid, each a closed, outward-oriented triangulation
  whose facets lie within :data:`STL_TOLERANCE_MM` of the exact surface; the line that opens each
  block says ``unit: mm``.
"""
from __future__ import annotations

import contextlib
import logging
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from snapjump_cli.geometry.caps import CapScene, Design, cap_points, design_points

__all__ = ["SOLID_SUFFIXES", "STL_TOLERANCE_MM", "Solid", "scene_solids", "write_solids", "solid_volumes_text"]

log = logging.getLogger(__name__)

#: File formats :func:`write_solids` writes.
SOLID_SUFFIXES = (".step", ".stp", ".brep", ".stl")
#: Largest distance of an STL facet from the exact surface [mm].
STL_TOLERANCE_MM = 0.02


@dataclass(frozen=True)
class Solid:
    """One solid of revolution about the ``z`` axis [mm].

    ``kind`` ``"shell"``: the part of the shell between the spheres of radii ``r_in < r_out``
    centred at ``(0, 0, zc)`` above the plane ``z = z0``; ``kind`` ``"annulus"``: ``r_in <= r <=
    r_out``, ``z0 <= z <= z0 + h``."""

    name: str
    kind: str
    r_in: float
    r_out: float
    z0: float
    zc: float = 0.0
    h: float = 0.0

    def volume(self) -> float:
        """The exact volume [mm^3]."""
        if self.kind == "annulus":
            return math.pi * (self.r_out**2 - self.r_in**2) * self.h
        return _ball_above(self.r_out, self.z0 - self.zc) - _ball_above(self.r_in, self.z0 - self.zc)


def _ball_above(rho: float, c: float) -> float:
    if c >= rho:
        return 0.0
    h = rho - c
    return math.pi * h * h * (2.0 * rho + c) / 3.0


def scene_solids(scene: Design | CapScene) -> list[Solid]:
    """The solids of a design or a single cap, in millimetres, the ground at ``z = 0``."""
    mm = 1e3
    if isinstance(scene, Design):
        p = design_points(scene)
        ground = p["8"][1]
        yb = p["7"][1]
        ai, bi = scene.R_i * (1 - 0.5 / scene.eta_i), scene.R_i * (1 + 0.5 / scene.eta_i)
        ao, bo = scene.R_o * (1 - 0.5 / scene.eta_o), scene.R_o * (1 + 0.5 / scene.eta_o)
        return [
            Solid("inner_cap", "shell", ai * mm, bi * mm, (yb - ground) * mm, (0.0 - ground) * mm),
            Solid("ring", "annulus", p["8"][0] * mm, p["9"][0] * mm, 0.0, h=scene.t_ring * mm),
            Solid("outer_cap", "shell", ao * mm, bo * mm, (yb - ground) * mm, (scene.Delta - ground) * mm),
        ]
    p = cap_points(scene)
    yb = p["base_inner"][1]
    ground = p["ring_8"][1] if "ring_8" in p else yb
    a, b = scene.R * (1 - 0.5 / scene.eta), scene.R * (1 + 0.5 / scene.eta)
    out = [Solid(f"{scene.kind}_cap", "shell", a * mm, b * mm, (yb - ground) * mm, (0.0 - ground) * mm)]
    if "ring_8" in p:
        out.append(Solid("ring", "annulus", p["ring_8"][0] * mm, p["ring_9"][0] * mm, 0.0, h=scene.t_ring * mm))
    return out


def _build(gmsh, solids: list[Solid]) -> list[int]:
    """The OCC solids of ``solids`` (volume tags, in order)."""
    occ = gmsh.model.occ
    tags = []
    for s in solids:
        if s.kind == "annulus":
            outer = occ.addCylinder(0, 0, s.z0, 0, 0, s.h, s.r_out)
            inner = occ.addCylinder(0, 0, s.z0, 0, 0, s.h, s.r_in)
            res, _ = occ.cut([(3, outer)], [(3, inner)])
        else:
            big = occ.addSphere(0, 0, s.zc, s.r_out)
            small = occ.addSphere(0, 0, s.zc, s.r_in)
            w = 2.5 * s.r_out
            half = occ.addBox(-w, -w, s.z0, 2 * w, 2 * w, s.zc + s.r_out - s.z0 + w)
            cut, _ = occ.intersect([(3, big)], [(3, half)])
            res, _ = occ.cut(cut, [(3, small)])
        if len(res) != 1 or res[0][0] != 3:
            raise RuntimeError(f"OpenCASCADE gave {len(res)} pieces for the {s.name}")
        tags.append(res[0][1])
    occ.synchronize()
    return tags


@contextlib.contextmanager
def _quiet_stdout():
    """OpenCASCADE's STEP writer prints its statistics to the C-level stdout: send them to /dev/null
    (stdout carries the command's JSON)."""
    import sys

    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 1)
            yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def _name_step_products(text: str, names: list[str], top: str) -> str:
    """Name the STEP file's products: the assembly ``top`` and one part per solid, in order."""
    prods = list(re.finditer(r"(?<![A-Z_])PRODUCT\('[^']*',\s*'[^']*'", text))
    labels = [top, *names] if len(prods) == len(names) + 1 else names
    if len(prods) != len(labels):
        raise RuntimeError(f"the STEP file has {len(prods)} products for {len(names)} solids")
    out, pos = [], 0
    for m, label in zip(prods, labels):
        out += [text[pos : m.start()], f"PRODUCT('{label}','{label}'"]
        pos = m.end()
    return "".join(out + [text[pos:]])


def _stl_text(gmsh, solids: list[Solid], tags: list[int], header: str) -> str:
    """ASCII STL, one closed outward-oriented block per solid (facets within STL_TOLERANCE_MM)."""
    r_max = max(s.r_out for s in solids)
    n = int(math.ceil(math.pi * math.sqrt(r_max / (2.0 * STL_TOLERANCE_MM))))  # chord error pi^2 rho / (2 n^2)
    opt = gmsh.option
    opt.setNumber("Mesh.MeshSizeFromCurvature", n)
    opt.setNumber("Mesh.MeshSizeMax", 2.0 * math.pi * r_max / n)
    opt.setNumber("Mesh.MeshSizeExtendFromBoundary", 1)
    opt.setNumber("Mesh.Algorithm", 6)
    gmsh.model.mesh.generate(2)
    node_tags, coords, _ = gmsh.model.mesh.getNodes()
    xyz = np.zeros((int(node_tags.max()) + 1, 3))
    xyz[node_tags.astype(int)] = coords.reshape(-1, 3)
    lines = []
    for s, vol in zip(solids, tags):
        surfaces = [abs(t) for _, t in gmsh.model.getBoundary([(3, vol)], combined=False, oriented=False)]
        tris = [gmsh.model.mesh.getElementsByType(2, t)[1].astype(int).reshape(-1, 3) for t in surfaces]
        T = np.concatenate([t[:, ::-1] if f else t for t, f in zip(tris, _consistent_flips(tris))])
        P = xyz[T]
        if np.einsum("ij,ij->i", P[:, 0], np.cross(P[:, 1], P[:, 2])).sum() < 0:  # oriented inward
            T, P = T[:, ::-1], P[:, ::-1]
        nrm = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
        nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)
        lines.append(f"solid {s.name} ({header})")
        for nv, tri in zip(nrm, P):
            lines.append(f"  facet normal {nv[0]:.6e} {nv[1]:.6e} {nv[2]:.6e}\n    outer loop")
            lines += [f"      vertex {v[0]:.9e} {v[1]:.9e} {v[2]:.9e}" for v in tri]
            lines.append("    endloop\n  endfacet")
        lines.append(f"endsolid {s.name}")
    return "\n".join(lines) + "\n"


def _consistent_flips(tris: list[np.ndarray]) -> list[bool]:
    """Which surfaces' triangles to reverse so that the closed surface they make is consistently
    oriented (each shared edge run in opposite directions by its two sides); the surfaces' own
    triangles are consistent (gmsh), their orientation relative to the solid is not known."""
    owner: dict[tuple[int, int], tuple[int, bool]] = {}  # undirected edge -> (surface, runs low->high)
    links: list[list[tuple[int, bool]]] = [[] for _ in tris]
    for k, t in enumerate(tris):
        for a, b in ((t[:, 0], t[:, 1]), (t[:, 1], t[:, 2]), (t[:, 2], t[:, 0])):
            for u, v in zip(a.tolist(), b.tolist()):
                key = (min(u, v), max(u, v))
                if key in owner and owner[key][0] != k:
                    j, up = owner[key]
                    same = up == (u < v)  # both run the edge the same way: one of them must turn
                    links[k].append((j, same))
                    links[j].append((k, same))
                else:
                    owner[key] = (k, u < v)
    flip: list[bool | None] = [None] * len(tris)
    for start in range(len(tris)):
        if flip[start] is not None:
            continue
        flip[start] = False
        todo = [start]
        while todo:
            k = todo.pop()
            for j, same in links[k]:
                if flip[j] is None:
                    flip[j] = flip[k] != same
                    todo.append(j)
    return [bool(f) for f in flip]


def solid_volumes_text(solids: list[Solid]) -> str:
    """The solids' exact volumes, named so that they add up visibly: ``volumes [cm^3]: inner_cap
    9.87 + ring 1.35 = inner solid (the mass m_i) 11.22; outer_cap 9.17 = outer solid (m_o)``."""
    cm3 = {s.name: s.volume() * 1e-3 for s in solids}
    parts = []
    inner = [n for n in ("inner_cap", "ring") if n in cm3]
    if inner:
        parts.append(" + ".join(f"{n} {cm3[n]:.6g}" for n in inner)
                     + (f" = inner solid {sum(cm3[n] for n in inner):.6g}" if len(inner) > 1 else ""))
    if "outer_cap" in cm3:
        parts.append(f"outer_cap {cm3['outer_cap']:.6g}" + (" = outer solid" if inner else ""))
    return "volumes [cm^3]: " + "; ".join(parts)


def write_solids(scene: Design | CapScene, path: str | os.PathLike) -> Path:
    """Write the scene's solids (module docstring) to ``path`` (``.step``/``.stp``, ``.brep`` or
    ``.stl``), atomically. Returns the path."""
    from snapjump_cli.files import write_atomic
    from snapjump_cli.mesh.gmsh_session import gmsh_session

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in SOLID_SUFFIXES:
        raise ValueError(f"solid file must end in {', '.join(SOLID_SUFFIXES)}, got {str(path)!r}")
    solids = scene_solids(scene)
    names = [s.name for s in solids]
    label = getattr(scene, "name", None) or ("design" if isinstance(scene, Design) else f"{scene.kind}_cap")
    header = f"snapjump {label}; unit: mm; axis z, ground z = 0; solids: {', '.join(names)}"
    full = f"{header}; {solid_volumes_text(solids)}"  # (OpenCASCADE's BREP reader refuses it in a comment)

    def write(tmp: Path) -> None:
        with gmsh_session("snapjump_solids") as gmsh:
            tags = _build(gmsh, solids)
            if suffix == ".stl":
                tmp.write_text(_stl_text(gmsh, solids, tags, full), encoding="ascii")
                return
            scratch = tmp.with_name(tmp.stem + ".raw" + (".step" if suffix in (".step", ".stp") else ".brep"))
            try:
                if suffix == ".brep":
                    gmsh.write(str(scratch))
                    tmp.write_text(f"# {header}\n" + scratch.read_text(), encoding="utf-8")
                else:
                    gmsh.option.setString("Geometry.OCCSTEPDescription", full)
                    gmsh.option.setString("Geometry.OCCSTEPModelName", f"snapjump_{label}")
                    with _quiet_stdout():
                        gmsh.write(str(scratch))
                    text = _name_step_products(scratch.read_text(), names, f"snapjump_{label}")
                    tmp.write_text(text, encoding="utf-8")
            finally:
                scratch.unlink(missing_ok=True)

    return write_atomic(path, write)
