"""Solver settings shared by ``curve`` and ``sweep`` (one place for every numerical default)."""
from __future__ import annotations

from dataclasses import dataclass, asdict, fields

__all__ = ["MeshSettings", "SolverSettings", "SettingsError", "NT_MAX", "ASPECT_MAX", "LIMIT_SETTINGS", "without_limits"]

#: Bounds of the mesh density, the same for the YAML configs and the command-line options.
NT_MAX = 64
ASPECT_MAX = 100.0
#: The solver settings that bound a design's resources (CPU time, mesh size) without changing its
#: answer: left out of design keys, of a row's ``solver_settings`` and of the comparison of runs.
#: (``follow_mode`` is not one: where two stable states coexist at the snap's volume the actuator
#: mode and the reference may land on different ones; docs/harmonics.md section 10.8.)
LIMIT_SETTINGS: tuple[str, ...] = ("time_limit_s", "max_nodes")


def without_limits(solver: object) -> object:
    """A solver-settings mapping (e.g. read back from a file's metadata) without
    :data:`LIMIT_SETTINGS`, for comparing runs; anything else is returned unchanged."""
    if isinstance(solver, dict):
        return {k: v for k, v in solver.items() if k not in LIMIT_SETTINGS}
    return solver


class SettingsError(ValueError):
    """A setting out of its range: ``field``, what was ``expected``, the ``value`` given."""

    def __init__(self, field: str, expected: str, value: object) -> None:
        super().__init__(f"{field}: expected {expected}, got {value!r}")
        self.field, self.expected, self.value = field, expected, value


def _check(obj: object, rules: dict) -> None:
    """Validate the fields of a settings dataclass: ``rules[name] = (test, wording)``."""
    import math

    for name, (test, expected) in rules.items():
        v = getattr(obj, name)
        if isinstance(v, float) and not math.isfinite(v):
            raise SettingsError(name, expected, v)
        if not test(v):
            raise SettingsError(name, expected, v)


def _is_int(v: object) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_num(v: object) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


@dataclass(frozen=True)
class MeshSettings:
    """Mesh density.

    Parameters
    ----------
    order : 1 (bilinear Q4, mean dilatation) or 2 (biquadratic Q9, linear discontinuous pressure)
    nt : elements through the thickness of each cap (the thinnest cap gets at least this many)
    aspect : maximum element aspect ratio (length along the arc / size through the thickness)
    """

    order: int = 2
    nt: int = 2
    aspect: float = 2.0

    def __post_init__(self) -> None:
        _check(self, {
            "order": (lambda v: _is_int(v) and v in (1, 2), "1 or 2"),
            "nt": (lambda v: _is_int(v) and 1 <= v <= NT_MAX, f"an integer in [1, {NT_MAX}]"),
            "aspect": (lambda v: _is_num(v) and 0 < v <= ASPECT_MAX, f"a number in (0, {ASPECT_MAX:g}]"),
        })

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class SolverSettings:
    """Continuation and Newton settings (all in scaled units: lengths / R_i, stresses / mu_i).

    Parameters
    ----------
    tol : relative Newton tolerance on the residual (scaled by the load norm)
    ds0 : initial arc length (scaled), used as given. (Before the settings were unified, the
        continuation silently multiplied it by 2.5: the old default 0.02 meant 0.05, the default
        now; a config that gave ``ds0: X`` then took steps of 2.5 X and now takes X.)
    ds_max : maximum arc length (scaled)
    max_steps : bound on continuation steps; three quarters of it bound the post-snap path's way
        back to V* (beyond that the lower state is sought at fixed volume)
    max_newton : Newton iterations per step before a cut-back
    max_turn_deg : largest allowed turn of the path tangent between steps (catches small folds)
    full : trace the whole curve (to 1.5 p_c or the volume bound) instead of stopping once the snap
        is characterised
    bulk_ratio : kappa / mu of the volumetric penalty of the mixed formulation
    tol_path : Newton tolerance of ordinary path points (an error test: the last Newton correction,
        in the arc-length metric); the limit point, the lower state and the descent always use
        ``tol`` (a residual test)
    harmonics : check the traced states against non-axisymmetric perturbations ``cos n phi``,
        ``n = 1..harmonics`` (:mod:`snapjump_cli.fe.stability.harmonics`; 0 = off, the default)
    u_scale : scale of the RMS displacement in the arc length, in units of the pole-displacement
        scale (0 = arc length in (V, p, pole) only)
    follow : when the harmonic check finds a harmonic unstable before V*, trace the branch that
        bifurcates there (:mod:`snapjump_cli.fe.branch.trace`) and report its snap as the design's answer
        (needs ``harmonics >= 1``; the axisymmetric answer is kept in the ``axisym_*`` keys)
    follow_N : highest harmonic of the followed branch's Fourier series (0 = the default,
        ``4 n_c`` for the critical harmonic ``n_c``)
    follow_mode : ``"actuator"`` (the default) traces only what the actuator passes through and
        lands a subcritical ``n = 1`` snap on the axisymmetric path's inverted state where that
        state is stable (:func:`snapjump_cli.fe.branch.followed.followed_metrics`); ``"full"`` is
        the reference: every branch traced to its snap and its lower state searched
    margins : report the smallest eigenvalue of every harmonic's tangent ``n = 0..harmonics`` along
        the loading path (:mod:`snapjump_cli.fe.stability.margins`; needs ``harmonics >= 1``; about one
        shift-invert eigenvalue solve per harmonic and path state: several times the solve)
    time_limit_s : CPU seconds one design (or scene) may take, the mesh check's re-solve and the
        harmonic check included; beyond it the solve stops with a failure saying so (the paper
        grid's slowest design takes about 1.3 s)
    max_nodes : largest mesh solved, in nodes; a larger one is refused before it is solved (and,
        when the count is already clear from the element counts, before it is meshed), saying its
        size (the paper grid's largest mesh has 333 nodes, 1707 at nt 4)
    """

    tol: float = 1e-8
    ds0: float = 0.05
    ds_max: float = 1.0
    max_steps: int = 2000
    max_newton: int = 8
    max_turn_deg: float = 10.0
    full: bool = False
    bulk_ratio: float = 1.0e4
    u_scale: float = 1.0
    tol_path: float = 1e-6
    harmonics: int = 0
    follow: bool = False
    follow_N: int = 0
    follow_mode: str = "actuator"
    margins: bool = False
    time_limit_s: float = 300.0
    max_nodes: int = 20_000

    def __post_init__(self) -> None:
        _check(self, {
            "tol": (lambda v: _is_num(v) and 0 < v <= 1e-2, "a number in (0, 0.01]"),
            "tol_path": (lambda v: _is_num(v) and 0 < v <= 1e-2, "a number in (0, 0.01]"),
            "ds0": (lambda v: _is_num(v) and v > 0, "a number > 0"),
            "ds_max": (lambda v: _is_num(v) and v >= self.ds0, f"a number >= ds0 = {self.ds0:g}"),
            "max_steps": (lambda v: _is_int(v) and 1 <= v <= 1_000_000, "an integer in [1, 1000000]"),
            "max_newton": (lambda v: _is_int(v) and 1 <= v <= 100, "an integer in [1, 100]"),
            "max_turn_deg": (lambda v: _is_num(v) and 0 < v <= 90, "a number of degrees in (0, 90]"),
            "full": (lambda v: isinstance(v, bool), "true or false"),
            "bulk_ratio": (lambda v: _is_num(v) and v > 0, "a number > 0"),
            "u_scale": (lambda v: _is_num(v) and v >= 0, "a number >= 0"),
            "harmonics": (lambda v: _is_int(v) and 0 <= v <= 64, "an integer in [0, 64]"),
            "follow": (lambda v: isinstance(v, bool) and (not v or self.harmonics >= 1),
                       "true or false (true needs harmonics >= 1)"),
            "follow_N": (lambda v: _is_int(v) and 0 <= v <= 16, "an integer in [0, 16]"),
            "follow_mode": (lambda v: v in ("actuator", "full"), '"actuator" or "full"'),
            "margins": (lambda v: isinstance(v, bool) and (not v or self.harmonics >= 1),
                        "true or false (true needs harmonics >= 1)"),
            "time_limit_s": (lambda v: _is_num(v) and v > 0, "a number of seconds > 0"),
            "max_nodes": (lambda v: _is_int(v) and 10 <= v <= 10_000_000, "an integer in [10, 10000000]"),
        })

    def as_dict(self) -> dict:
        return asdict(self)

    def numerics(self) -> dict:
        """The settings that decide the answer: :meth:`as_dict` without :data:`LIMIT_SETTINGS`."""
        return {k: v for k, v in asdict(self).items() if k not in LIMIT_SETTINGS}

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))


#: The jump model's defaults (docs/physics.md section 6), the one source of ``JumpParams`` and of
#: ``snapjump rank``'s options: rubber density [kg/m^3], dashpot coefficient [kg/s] and the
#: ground's coefficient of restitution (eq 25).
JUMP_RHO = 1000.0
JUMP_C_D = 0.4
JUMP_ALPHA = 0.5
