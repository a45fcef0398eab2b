"""``snapjump mesh``: build and mesh one scene, print its geometry (text or JSON), optionally write
the mesh (.msh or .vtu) or the designed solids for CAD (.step/.stp, .brep, .stl; millimetres).

JSON keys (stable): ``R_o_m``, ``Delta_m``, ``n_nodes``, ``n_elements``, ``V_inner_solid_m3``
(inner cap + ring, meshed), ``V_outer_solid_m3`` (meshed), ``V_cavity_m3`` (meshed, exact
boundary integral), ``h_pole_m`` (lower-surface inner pole above the ring's ground face); keys that
do not apply to a scene are null. Extra keys: ``scene``, ``name``, ``order``, ``nt``, ``aspect``,
exact volumes of the meshed geometry (``*_exact_m3``), ``V_under_m3`` (single caps), ``overhang``,
``ring_snapped``, ``mesh_s``, ``out``.
"""
from __future__ import annotations

import json
import logging
import sys
from pathlib import Path
from typing import Sequence

import click

from snapjump_cli.cli import verbosity_options
from snapjump_cli.errors import BadInput
from snapjump_cli.settings import SolverSettings
from snapjump_cli.commands.options import (
    mesh_options,
    mesh_settings_from_options,
    pick_mesh_options,
    pick_scene_options,
    scene_from_options,
    scene_options,
)

__all__ = ["command", "main", "summary"]

log = logging.getLogger(__name__)


def summary(scene, mesh) -> dict:
    """The JSON summary of a meshed scene (see the module docstring)."""
    from snapjump_kernels.calls import cavity_volume

    from snapjump_cli.geometry.caps import Design, cap_points, cap_volumes, design_points, design_volumes
    from snapjump_cli.mesh.build import meshed_design, solid_volumes

    vol = solid_volumes(mesh)
    out: dict = {
        "scene": mesh.scene,
        "name": getattr(scene, "name", None),
        "R_o_m": None,
        "Delta_m": None,
        "n_nodes": mesh.n_nodes,
        "n_elements": mesh.n_elements,
        "V_inner_solid_m3": None,
        "V_outer_solid_m3": None,
        "V_cavity_m3": None,
        "h_pole_m": None,
    }
    if isinstance(scene, Design):
        pts = design_points(scene)
        ex = design_volumes(meshed_design(scene, mesh))  # the ring width may be snapped onto x5
        out.update(
            R_o_m=scene.R_o,
            Delta_m=scene.Delta,
            V_inner_solid_m3=vol["inner_solid"],
            V_outer_solid_m3=vol["outer_solid"],
            V_cavity_m3=float(cavity_volume(mesh.nodes, mesh.cavity_edges)) + mesh.cavity_volume_offset,
            h_pole_m=pts["1"][1] - pts["8"][1],
            V_inner_solid_exact_m3=ex["inner_solid"],
            V_outer_solid_exact_m3=ex["outer_solid"],
            V_cavity_exact_m3=ex["cavity"],
            overhang=bool(mesh.info.get("overhang", False)),
            ring_snapped=bool(mesh.info.get("ring_snapped", False)),
        )
    else:
        pts = cap_points(scene)
        ex = cap_volumes(scene)
        key = "V_outer_solid_m3" if scene.kind == "outer" else "V_inner_solid_m3"
        out[key] = vol["outer_solid"] if scene.kind == "outer" else vol["inner_solid"]
        out[key.replace("_m3", "_exact_m3")] = ex["solid"]
        if scene.kind == "outer":
            out["R_o_m"] = scene.R
        out["V_under_m3"] = abs(mesh.cavity_volume_offset)
        out["V_under_exact_m3"] = ex["under"]
        if "ring_8" in pts:
            out["h_pole_m"] = pts["pole_lower"][1] - pts["ring_8"][1]
        out["bc"] = "fixed" if scene.kind == "outer" else scene.bc
    out.update(order=mesh.order, nt=dict(mesh.info.get("nt", {})), aspect=mesh.info.get("aspect"),
               mesh_s=mesh.info.get("mesh_s"))
    return out


def _describe(scene) -> str:
    from snapjump_cli.geometry.caps import Design

    if isinstance(scene, Design):
        label = f"design {scene.name}" if scene.name else "design"
        return (f"{label}: eta_i={scene.eta_i:g}, theta_i={scene.theta_i_deg:g} deg, eta_o={scene.eta_o:g}, "
                f"theta_o={scene.theta_o_deg:g} deg, mu_i/mu_o={scene.mu_ratio:g}, R_i={scene.R_i * 1e3:g} mm")
    bc = "base fixed" if scene.kind == "outer" else f"bc={scene.bc}"
    return f"{scene.kind} cap: eta={scene.eta:g}, theta={scene.theta_deg:g} deg, R={scene.R * 1e3:g} mm, {bc}"


def _text(scene, s: dict) -> str:
    def mm(v):
        return "-" if v is None else f"{v * 1e3:.6g} mm"

    def cm3(v, exact=None):
        if v is None:
            return "-"
        txt = f"{v * 1e6:.8g} cm^3"
        if exact:
            txt += f" (exact {exact * 1e6:.8g}, rel. err {v / exact - 1:+.2e})"
        return txt

    nt = ", ".join(f"{k} {v}" for k, v in s["nt"].items())
    lines = [
        _describe(scene),
        f"  R_o = {mm(s['R_o_m'])}, Delta = {mm(s['Delta_m'])}, h_pole = {mm(s['h_pole_m'])}",
        f"  mesh: order {s['order']}, {s['n_nodes']} nodes, {s['n_elements']} elements "
        f"(through thickness: {nt}; aspect <= {s['aspect']:g}) in {1e3 * s['mesh_s']:.1f} ms",
        f"  V inner solid = {cm3(s['V_inner_solid_m3'], s.get('V_inner_solid_exact_m3'))}",
        f"  V outer solid = {cm3(s['V_outer_solid_m3'], s.get('V_outer_solid_exact_m3'))}",
    ]
    if s["V_cavity_m3"] is not None:
        lines.append(f"  V cavity      = {cm3(s['V_cavity_m3'], s.get('V_cavity_exact_m3'))}")
    if "V_under_m3" in s:
        lines.append(f"  V under loaded surface = {cm3(s['V_under_m3'], s.get('V_under_exact_m3'))}")
    if s.get("overhang"):
        lines.append("  note: the outer cap's base overhangs the ring (x5 > x10): its outer part is free")
    if s.get("ring_snapped"):
        lines.append("  note: x5 and x10 nearly coincide: the ring's outer face was moved onto x5 (no sliver)")
    if s.get("out"):
        lines.append(f"  written: {s['out']}")
    return "\n".join(lines)


@click.command("mesh", context_settings={"help_option_names": ["-h", "--help"]})
@scene_options
@mesh_options
@click.option("--out", "out", type=click.Path(dir_okay=False, path_type=Path), default=None, metavar="FILE",
              help="Write the mesh to FILE (.msh or .vtu), or the designed actuator as 3D solids for CAD and "
                   "moulds (.step/.stp, .brep, .stl; separate solids inner_cap, ring, outer_cap; unit mm, axis z, "
                   "ground at z = 0).")
@click.option("--overwrite", is_flag=True, help="Replace an existing --out file (refused by default).")
@click.option("--max-nodes", type=click.IntRange(10, 10_000_000), default=SolverSettings().max_nodes,
              show_default=True, metavar="N",
              help="Refuse a mesh of more than N nodes (before meshing when the element counts already tell).")
@click.option("--format", "fmt", type=click.Choice(["text", "json"]), default="text", show_default=True,
              help="Output format.")
@verbosity_options
def command(out: Path | None, fmt: str, overwrite: bool, max_nodes: int, **kw) -> None:
    """Build and mesh one scene (design or single cap); print its geometry.

    Choose the scene with --design NAME, or --eta-i/--theta-i/--eta-o/--theta-o [--mu-ratio],
    or --cap [inner|outer] --theta DEG --eta ETA [--bc ...]. Angles in degrees.

    \b
    Examples:
      snapjump mesh --design D --out d.vtu          # the FE mesh (ParaView)
      snapjump mesh --design D --out d.step         # the solids for CAD, in millimetres
      snapjump mesh --cap --theta 60 --eta 8.5 --bc ring-roller --out cap.stl
    """
    from snapjump_cli.files import check_writable
    from snapjump_cli.mesh.build import MESH_SUFFIXES, mesh_scene, write_mesh
    from snapjump_cli.mesh.solids import SOLID_SUFFIXES, write_solids

    scene = scene_from_options(**pick_scene_options(kw))
    settings = mesh_settings_from_options(**pick_mesh_options(kw))
    if out is not None:
        if out.suffix.lower() not in MESH_SUFFIXES + SOLID_SUFFIXES:
            raise BadInput(f"--out must end in .msh or .vtu (the mesh) or .step, .stp, .brep, .stl (the solids, mm), "
                           f"got {str(out)!r}")
        if not out.parent.is_dir():
            raise BadInput(f"--out folder does not exist: {str(out.parent)!r}")
        check_writable(out, BadInput, overwrite=overwrite)
    try:
        mesh = mesh_scene(scene, settings, max_nodes=max_nodes)
    except (RuntimeError, ValueError) as e:  # gmsh or mesh-validity failure, too many nodes: one line, exit 1
        raise click.ClickException(f"meshing failed: {' '.join(str(e).split())}") from None
    s = summary(scene, mesh)
    if out is not None:
        try:
            if out.suffix.lower() in SOLID_SUFFIXES:
                write_solids(scene, out)
            else:
                write_mesh(mesh, out)
        except OSError as e:  # a full disk, an I/O error: one line naming the file, exit 2, nothing written
            from snapjump_cli.files import describe_os_error

            raise BadInput(describe_os_error(e, out)) from None
        s["out"] = str(out)
        log.info("wrote %s", out)
    if fmt == "json":
        click.echo(json.dumps(s, indent=2, allow_nan=False, default=_json_default))
    else:
        click.echo(_text(scene, s))


def _json_default(o):
    try:
        import numpy as np

        if isinstance(o, np.generic):
            return o.item()
    except ImportError:  # pragma: no cover
        pass
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``snapjump mesh ARGV``; returns the exit code (0 ok, 1 failure, 2 bad input)."""
    from snapjump_cli.cli import main as cli_main

    return cli_main(["mesh", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
