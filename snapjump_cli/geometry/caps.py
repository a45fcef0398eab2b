"""Actuator and single-cap geometry (paper S1, eqs 1-6; docs/physics.md section 1).

All lengths in metres, angles in degrees at the interface (``*_deg`` fields) and
radians inside. Coordinates are axisymmetric ``(x, y) = (r, z)``: ``x`` is the
distance from the symmetry axis, ``y`` the height.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, asdict
from typing import Literal

__all__ = [
    "InvalidDesign",
    "Design",
    "CapScene",
    "BaseCondition",
    "BASE_CONDITIONS",
    "outer_radius",
    "centre_offset",
    "design_points",
    "cap_points",
    "spherical_cap_volume",
    "design_volumes",
    "cap_volumes",
]

BaseCondition = Literal["clamped", "roller", "roller-point", "ring-roller"]
#: Base conditions of a single inner cap (docs/physics.md section 1). ``outer`` caps always have
#: a fixed base.
BASE_CONDITIONS: tuple[str, ...] = ("clamped", "roller", "roller-point", "ring-roller")

MU_ELITE_DOUBLE_32 = 0.35e6  # Pa
R_I_DEFAULT = 0.030  # m
#: The radii (R_i of a design, R of a cap) the model accepts: a micrometre to a kilometre (the
#: scaled model is size-free, but a radius far outside this range overflows the SI outputs).
RADIUS_RANGE_M = (1e-6, 1e3)
J_M_DEFAULT = 24.0


class InvalidDesign(ValueError):
    """A design or scene whose parameters cannot describe a meshable actuator.

    The message names the offending parameter or the violated inequality with its numbers.
    """


def _check_finite_positive(name: str, value: float) -> None:
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        raise InvalidDesign(f"{name} must be a number, got {value!r}")
    if math.isnan(value) or math.isinf(value):
        raise InvalidDesign(f"{name} must be finite, got {value}")
    if value <= 0.0:
        raise InvalidDesign(f"{name} must be > 0, got {value}")


def _check_radius(name: str, value: float) -> None:
    _check_finite_positive(name, value)
    lo, hi = RADIUS_RANGE_M
    if not lo <= value <= hi:
        raise InvalidDesign(f"{name} must lie in [{lo:g}, {hi:g}] m, got {value:g}")


def _check_angle(name: str, deg: float) -> None:
    if not isinstance(deg, (int, float)) or isinstance(deg, bool) or not math.isfinite(deg):
        raise InvalidDesign(f"{name} must be a finite number of degrees, got {deg!r}")
    if not (0.0 < deg < 180.0):
        raise InvalidDesign(f"{name} must lie in (0, 180) degrees, got {deg}")


def _check_eta(name: str, eta: float) -> None:
    _check_finite_positive(name, eta)
    if eta <= 0.5:
        raise InvalidDesign(f"{name} = R/t must be > 0.5 (the inner surface radius must be positive), got {eta}")


@dataclass(frozen=True)
class Design:
    """A full actuator: inner cap (+ ring) and outer cap on a common base plane.

    Parameters
    ----------
    eta_i, theta_i_deg, eta_o, theta_o_deg
        Normalised radii ``R/t`` and polar angles (degrees) of the inner and outer caps.
    mu_ratio
        ``mu_i / mu_o``.
    R_i
        Mid-surface radius of the inner cap [m].
    mu_i
        Initial shear modulus of the inner cap and ring [Pa].
    J_m
        Gent locking parameter (both rubbers).
    t_ring_frac, w_ring_frac
        Ring thickness and width as fractions of ``R_i`` (paper: 1/30 and 1/10).
    name
        Optional label (named designs A-D, S20b, S20c).
    """

    eta_i: float
    theta_i_deg: float
    eta_o: float
    theta_o_deg: float
    mu_ratio: float
    R_i: float = R_I_DEFAULT
    mu_i: float = MU_ELITE_DOUBLE_32
    J_m: float = J_M_DEFAULT
    t_ring_frac: float = 1.0 / 30.0
    w_ring_frac: float = 1.0 / 10.0
    name: str | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        _check_eta("eta_i", self.eta_i)
        _check_eta("eta_o", self.eta_o)
        _check_angle("theta_i", self.theta_i_deg)
        _check_angle("theta_o", self.theta_o_deg)
        for n in ("mu_ratio", "R_i", "mu_i", "J_m", "t_ring_frac", "w_ring_frac"):
            _check_finite_positive(n, getattr(self, n))
        _check_radius("R_i", self.R_i)
        validate_design(self)

    # ---- derived quantities -------------------------------------------------
    @property
    def theta_i(self) -> float:
        return math.radians(self.theta_i_deg)

    @property
    def theta_o(self) -> float:
        return math.radians(self.theta_o_deg)

    @property
    def mu_o(self) -> float:
        return self.mu_i / self.mu_ratio

    @property
    def t_i(self) -> float:
        return self.R_i / self.eta_i

    @property
    def R_o(self) -> float:
        return outer_radius(self.eta_i, self.theta_i, self.eta_o, self.theta_o, self.R_i)

    @property
    def t_o(self) -> float:
        return self.R_o / self.eta_o

    @property
    def Delta(self) -> float:
        return centre_offset(self.eta_i, self.theta_i, self.eta_o, self.theta_o, self.R_i)

    @property
    def t_ring(self) -> float:
        return self.R_i * self.t_ring_frac

    @property
    def w_ring(self) -> float:
        return self.R_i * self.w_ring_frac

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class CapScene:
    """A single spherical cap (paper Fig. 1 and Fig. 3).

    Parameters
    ----------
    theta_deg, eta
        Polar angle (degrees) and normalised radius ``R/t``.
    kind
        ``"inner"``: loaded on its convex (upper) side, base condition ``bc``;
        ``"outer"``: loaded from its concave side, base fully fixed (S17B).
    bc
        Base condition of an inner cap, one of :data:`BASE_CONDITIONS`.
    R, mu, J_m
        Mid-surface radius [m], shear modulus [Pa], Gent parameter.
    t_ring_frac, w_ring_frac
        Ring size for ``bc="ring-roller"`` (fractions of ``R``).
    """

    theta_deg: float
    eta: float
    kind: Literal["inner", "outer"] = "inner"
    bc: str = "clamped"
    R: float = R_I_DEFAULT
    mu: float = MU_ELITE_DOUBLE_32
    J_m: float = J_M_DEFAULT
    t_ring_frac: float = 1.0 / 30.0
    w_ring_frac: float = 1.0 / 10.0

    def __post_init__(self) -> None:
        _check_eta("eta", self.eta)
        _check_angle("theta", self.theta_deg)
        for n in ("R", "mu", "J_m", "t_ring_frac", "w_ring_frac"):
            _check_finite_positive(n, getattr(self, n))
        _check_radius("R", self.R)
        if self.kind not in ("inner", "outer"):
            raise InvalidDesign(f"cap kind must be 'inner' or 'outer', got {self.kind!r}")
        if self.kind == "inner" and self.bc not in BASE_CONDITIONS:
            raise InvalidDesign(f"bc must be one of {', '.join(BASE_CONDITIONS)}, got {self.bc!r}")
        c = math.cos(self.theta)
        a = 1.0 - 0.5 / self.eta
        if a * a <= c * c:
            raise InvalidDesign(
                f"cap inner surface does not reach the base plane: (1 - 1/(2 eta))^2 = {a * a:.6g} "
                f"<= cos^2(theta) = {c * c:.6g}"
            )

    @property
    def theta(self) -> float:
        return math.radians(self.theta_deg)

    @property
    def t(self) -> float:
        return self.R / self.eta

    @property
    def t_ring(self) -> float:
        return self.R * self.t_ring_frac

    @property
    def w_ring(self) -> float:
        return self.R * self.w_ring_frac

    def as_dict(self) -> dict:
        return asdict(self)


# ---- eq 3 ---------------------------------------------------------------------
def _ratio(eta_i: float, theta_i: float, eta_o: float, theta_o: float) -> float:
    num = (1.0 + 0.5 / eta_i) ** 2 - math.cos(theta_i) ** 2
    den = (1.0 - 0.5 / eta_o) ** 2 - math.cos(theta_o) ** 2
    if den <= 0.0:
        raise InvalidDesign(
            f"outer cap inner surface does not reach the base plane: (1 - 1/(2 eta_o))^2 - cos^2(theta_o) = {den:.6g} <= 0"
        )
    return math.sqrt(num / den)


def outer_radius(eta_i: float, theta_i: float, eta_o: float, theta_o: float, R_i: float) -> float:
    """Outer-cap mid-surface radius ``R_o`` (eq 3a); angles in radians."""
    return R_i * _ratio(eta_i, theta_i, eta_o, theta_o)


def centre_offset(eta_i: float, theta_i: float, eta_o: float, theta_o: float, R_i: float) -> float:
    """Offset ``Delta`` of the outer sphere's centre above the inner one's (eq 3b); radians."""
    return R_i * (math.cos(theta_i) - math.cos(theta_o) * _ratio(eta_i, theta_i, eta_o, theta_o))


def design_points(d: Design) -> dict[str, tuple[float, float]]:
    """The cross-section points 1-10 of the manufacturable design (eqs 1, 6).

    Returns
    -------
    dict
        Keys ``"1"`` ... ``"5"``, ``"6i"``, ``"6o"``, ``"7"`` ... ``"10"``; values ``(x, y)`` in metres.
        ``"6i"`` and ``"6o"`` coincide (eq 2) to round-off.
    """
    Ri, ei, eo = d.R_i, d.eta_i, d.eta_o
    ci, co = math.cos(d.theta_i), math.cos(d.theta_o)
    Ro, De = d.R_o, d.Delta
    yb = Ri * ci
    x6i = Ri * math.sqrt((1 + 0.5 / ei) ** 2 - ci**2)
    x7 = Ri * math.sqrt((1 - 0.5 / ei) ** 2 - ci**2)
    pts = {
        "1": (0.0, Ri * (1 - 0.5 / ei)),
        "2": (0.0, Ri * (1 + 0.5 / ei)),
        "3": (0.0, Ro * (1 - 0.5 / eo) + De),
        "4": (0.0, Ro * (1 + 0.5 / eo) + De),
        "5": (Ro * math.sqrt((1 + 0.5 / eo) ** 2 - co**2), yb),
        "6i": (x6i, yb),
        "6o": (Ro * math.sqrt((1 - 0.5 / eo) ** 2 - co**2), Ro * co + De),
        "7": (x7, yb),
        "8": (x7, yb - d.t_ring),
        "9": (x6i + d.w_ring, yb - d.t_ring),
        "10": (x6i + d.w_ring, yb),
    }
    return pts


def validate_design(d: Design) -> None:
    """Raise :class:`InvalidDesign` naming the violated inequality (eq 5 and existence)."""
    ci = math.cos(d.theta_i)
    a_i = (1 - 0.5 / d.eta_i) ** 2
    if a_i <= ci**2:
        raise InvalidDesign(
            f"inner cap inner surface does not reach the base plane: (1 - 1/(2 eta_i))^2 = {a_i:.6g} <= cos^2(theta_i) = {ci**2:.6g}"
        )
    if not d.theta_i_deg < d.theta_o_deg:
        raise InvalidDesign(f"eq 5 violated: theta_i < theta_o required, got theta_i = {d.theta_i_deg} >= theta_o = {d.theta_o_deg}")
    pts = design_points(d)  # may raise for a non-existent R_o
    y2, y3 = pts["2"][1], pts["3"][1]
    if not y2 < y3:
        raise InvalidDesign(f"eq 5 violated: y_2 < y_3 required, got y_2 = {y2:.6g} m >= y_3 = {y3:.6g} m")


def cap_points(c: CapScene) -> dict[str, tuple[float, float]]:
    """Corner points of a single cap centred at the origin, cut by ``y = R cos(theta)``.

    Keys: ``pole_lower``, ``pole_upper`` (on the axis), ``base_inner``, ``base_outer`` (on the base
    plane) and, for ``bc="ring-roller"``, the ring corners ``ring_8``, ``ring_9``, ``ring_10``
    (same numbering as eq 6).
    """
    R, eta, co = c.R, c.eta, math.cos(c.theta)
    yb = R * co
    xo = R * math.sqrt((1 + 0.5 / eta) ** 2 - co**2)
    xi = R * math.sqrt((1 - 0.5 / eta) ** 2 - co**2)
    pts = {
        "pole_lower": (0.0, R * (1 - 0.5 / eta)),
        "pole_upper": (0.0, R * (1 + 0.5 / eta)),
        "base_inner": (xi, yb),
        "base_outer": (xo, yb),
    }
    if c.kind == "inner" and c.bc == "ring-roller":
        pts["ring_8"] = (xi, yb - c.t_ring)
        pts["ring_9"] = (xo + c.w_ring, yb - c.t_ring)
        pts["ring_10"] = (xo + c.w_ring, yb)
    return pts


# ---- exact volumes -------------------------------------------------------------
def spherical_cap_volume(rho: float, c: float) -> float:
    """Volume of the part of a ball of radius ``rho`` (centred at the origin) above ``y = c``."""
    if c >= rho:
        return 0.0
    if c <= -rho:
        return 4.0 / 3.0 * math.pi * rho**3
    h = rho - c
    return math.pi * h * h * (2.0 * rho + c) / 3.0


def design_volumes(d: Design) -> dict[str, float]:
    """Exact solid and cavity volumes of revolution of a design [m^3].

    Keys ``inner_cap``, ``ring``, ``inner_solid`` (cap + ring), ``outer_solid``, ``cavity``.
    """
    yb = d.R_i * math.cos(d.theta_i)
    ai, bi = d.R_i * (1 - 0.5 / d.eta_i), d.R_i * (1 + 0.5 / d.eta_i)
    ao, bo = d.R_o * (1 - 0.5 / d.eta_o), d.R_o * (1 + 0.5 / d.eta_o)
    p = design_points(d)
    inner = spherical_cap_volume(bi, yb) - spherical_cap_volume(ai, yb)
    ring = math.pi * (p["9"][0] ** 2 - p["8"][0] ** 2) * d.t_ring
    outer = spherical_cap_volume(bo, yb - d.Delta) - spherical_cap_volume(ao, yb - d.Delta)
    cavity = spherical_cap_volume(ao, yb - d.Delta) - spherical_cap_volume(bi, yb)
    return {"inner_cap": inner, "ring": ring, "inner_solid": inner + ring, "outer_solid": outer, "cavity": cavity}


def cap_volumes(c: CapScene) -> dict[str, float]:
    """Exact volumes of a single cap [m^3]: ``solid`` (cap + ring if any), ``ring`` and
    ``under`` = the solid of revolution between the loaded surface and the base plane
    (upper surface for inner caps, lower surface for outer caps)."""
    yb = c.R * math.cos(c.theta)
    a, b = c.R * (1 - 0.5 / c.eta), c.R * (1 + 0.5 / c.eta)
    p = cap_points(c)
    solid = spherical_cap_volume(b, yb) - spherical_cap_volume(a, yb)
    ring = 0.0
    if "ring_9" in p:
        ring = math.pi * (p["ring_9"][0] ** 2 - p["ring_8"][0] ** 2) * c.t_ring
    under = spherical_cap_volume(b if c.kind == "inner" else a, yb)
    return {"solid": solid + ring, "ring": ring, "under": under}
