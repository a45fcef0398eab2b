"""The result row's keys, declared once: one group per stage that produces them, with their types.

Below both the solver (:mod:`snapjump_cli.fe`) and the sweep (:mod:`snapjump_cli.sweep`): the
solver fills a design's metrics with these keys, the sweep's row contract
(:mod:`snapjump_cli.sweep.rows`) builds its columns, types and arrow schema from them. A stage's
group also names the keys it adds that are not row columns (diagnostics that
``snapjump curve --format json`` shows: ``column=False``).

The row's result columns are the column keys of :data:`STAGES`, in this order: the snap (and the
path's counts, the timing, the mesh), the mesh check, the harmonic check, the followed branch, the
margins, air.
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "Key",
    "SNAP",
    "MESH_CHECK",
    "HARMONIC_CHECK",
    "FOLLOWED",
    "MARGINS",
    "AIR",
    "STAGES",
    "TIMING_KEYS",
    "columns",
    "keys",
    "SNAP_VALUE_KEYS",
    "AIR_SNAP_KEYS",
]


@dataclass(frozen=True)
class Key:
    """One result key: its name, its type (``"float"``, ``"int"``, ``"bool"`` or ``"str"``),
    whether it is a row column, whether a float may be null in an ``ok`` row (``optional``), and
    (the snap's metrics) whether it is ``None`` when the scene does not snap (``snap_value``)."""

    name: str
    type: str = "float"
    column: bool = True
    optional: bool = False
    snap_value: bool = False


def _f(name: str, **kw) -> Key:
    return Key(name, "float", **kw)


def _i(name: str, **kw) -> Key:
    return Key(name, "int", **kw)


def _b(name: str, **kw) -> Key:
    return Key(name, "bool", **kw)


def _s(name: str, **kw) -> Key:
    return Key(name, "str", **kw)


#: The axisymmetric snap (:func:`snapjump_cli.fe.axisym.metrics.snap_metrics`), the path's counts,
#: the design's wall time and the mesh's sizes and solid volumes.
SNAP: tuple[Key, ...] = (
    _f("dE_J", snap_value=True), _f("dE_norm", snap_value=True), _f("dE_energy_J", snap_value=True),
    _f("dE_path_J", snap_value=True), _f("dE_rel_diff", snap_value=True),
    _f("dy_pole_m", snap_value=True), _f("dy_pole_upper_m", snap_value=True), _f("dy_pole_norm", snap_value=True),
    _f("p_star_Pa", snap_value=True), _f("V_star_m3", snap_value=True), _f("p_max_Pa"),
    _f("h_imp_m", snap_value=True), _f("L0_m", snap_value=True),
    _b("snaps"), _b("self_crossing"), _s("lower_state_method"),
    _i("n_steps"), _i("n_newton"), _f("wall_s"),
    _i("n_nodes"), _i("n_elements"), _i("n_dofs"),
    _f("V_inner_solid_m3"), _f("V_outer_solid_m3"),
)
#: The mesh check (:func:`snapjump_cli.fe.solve.solve_checked`): a suspicious snap re-solved on a finer mesh.
MESH_CHECK: tuple[Key, ...] = (
    _b("mesh_sensitive"), _f("dE_J_coarse", optional=True), _f("dy_pole_m_coarse", optional=True), _s("mesh_check"),
)
#: The harmonic check (:func:`snapjump_cli.fe.stability.harmonics.check_harmonics`; all null when
#: it is off), then its diagnostics.
HARMONIC_CHECK: tuple[Key, ...] = (
    _b("asym_first"), _i("asym_n"), _s("asym_ns", column=False), _f("asym_V_m3", optional=True),
    _f("asym_p_Pa", optional=True), _b("asym_lower_stable"), _i("asym_lower_n", column=False),
    _i("asym_n_max", column=False), _i("asym_states_checked", column=False), _f("asym_wall_s", column=False),
)
#: The followed branch (:func:`snapjump_cli.fe.branch.followed.apply_followed`, ``solver.follow``;
#: all null when it is off): ``followed`` says whether the row's dE_J, dy_pole_m, h_imp_m,
#: V_star_m3, p_star_Pa (and the keys derived from them) describe the branch that bifurcates from
#: the axisymmetric path (or, when that branch loses stability to other harmonics first, the
#: branch that leaves it there: ``follow_sec_n``, the dominant harmonic of that mode, and
#: ``follow_sec_V_m3``, the cavity volume there); the axisymmetric answer is kept in the
#: ``axisym_*`` keys.
FOLLOWED: tuple[Key, ...] = (
    _b("followed"), _i("follow_n"), _i("follow_N"), _s("follow_kind"), _f("follow_V_bif_m3", optional=True),
    _f("follow_p_bif_Pa", column=False), _i("follow_sec_n"), _f("follow_sec_V_m3", optional=True),
    _f("follow_sec_p_Pa", column=False), _s("follow_lower_method", column=False),
    _f("follow_dE_rel_diff", column=False), _f("follow_wall_s", column=False), _s("follow_note"),
    _f("axisym_dE_J", optional=True), _f("axisym_dy_pole_m", optional=True), _f("axisym_h_imp_m", optional=True),
    _f("axisym_V_star_m3", optional=True), _f("axisym_p_star_Pa", optional=True),
)
#: The margins (:func:`snapjump_cli.fe.stability.margins.path_margins`; null unless
#: ``solver: {margins: true}``).
MARGINS: tuple[Key, ...] = (
    _f("asym_margin", optional=True), _i("asym_margin_n"), _f("asym_margin_V_m3", optional=True),
)
#: A snap under air (``fluid: air``, :mod:`snapjump_cli.fe.axisym.air_snap`): the fluid, the gas
#: and the pressures, volumes and energies of the air snap, and the water snap's answers;
#: ``fluid`` is ``"water"`` and the others null in a water row.
AIR: tuple[Key, ...] = (
    _s("fluid"),
    *(_f(k, optional=True) for k in (
        "air_V0_m3", "air_gamma", "air_p0_Pa", "V_disp_m3", "p_before_Pa", "p_after_Pa", "dV_snap_m3",
        "dV_snap_eq9_m3", "dE_rubber_J", "dE_gas_J", "water_dE_J", "water_dy_pole_m", "water_h_imp_m")),
)

#: Every stage's keys, in the row's order.
STAGES: dict[str, tuple[Key, ...]] = {
    "snap": SNAP, "mesh_check": MESH_CHECK, "harmonic_check": HARMONIC_CHECK, "followed": FOLLOWED,
    "margins": MARGINS, "air": AIR,
}

#: The timing keys of a solve (``wall_s`` a row column, the others diagnostics), which the mesh
#: check sums over both solves of a re-solved design.
TIMING_KEYS: tuple[str, ...] = ("wall_s", "mesh_s", "t_assembly_s", "t_residual_s", "t_factor_s", "t_newton_s")

def keys(group: tuple[Key, ...]) -> tuple[str, ...]:
    """Every key of a stage's group (columns and diagnostics), in order."""
    return tuple(k.name for k in group)


def columns(group: tuple[Key, ...]) -> tuple[str, ...]:
    """The row columns of a stage's group, in order."""
    return tuple(k.name for k in group if k.column)


#: The snap's metrics that stay ``None`` without a snap (the first keys of the snap's metrics dict,
#: in this order).
SNAP_VALUE_KEYS: tuple[str, ...] = tuple(k.name for k in SNAP if k.snap_value)
#: The snap keys an air run takes from its air snap (the water snap's are kept as ``water_*``):
#: the snap's values, then the flags and the lower state's diagnostics.
AIR_SNAP_KEYS: tuple[str, ...] = SNAP_VALUE_KEYS + (
    "snaps", "lower_state_method", "lower_state_solver", "lower_state_note", "p_lower_Pa", "max_dilatation")
