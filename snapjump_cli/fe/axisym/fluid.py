"""The fluid that inflates the actuator: water (incompressible, the default) or air from a syringe.

:class:`FluidSettings` is the ``fluid:`` setting, shared by the command line (``curve --air-ml V
[--gamma G] [--p0 P]``) and the YAML configs (``fluid: {kind: air, V0_ml: 45, gamma: 1, p0:
101325}``): both build it, and its checks are the only ones. :class:`GasLaw` is the polytropic gas
in series with the actuator (docs/air.md): the syringe, the tube and the cavity hold a gas volume
``V0`` at the absolute pressure ``p0`` before inflation; at the gauge cavity pressure ``p`` the gas
occupies ``V_gas(p) = V0 (p0 / (p0 + p))^(1/gamma)``, and the volume the syringe has dispensed is
``V_d = (V - V_cav0) + V0 - V_gas(p)`` (paper S3, eqs 7-9).

Nothing here imports the solver: the configs and the command line use this module alone.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from snapjump_cli.settings import SettingsError

__all__ = ["FluidSettings", "GasLaw", "WATER", "FLUID_KINDS", "FLUID_KEYS", "GAMMA_RANGE", "P0_DEFAULT", "fluid_from_mapping"]

#: The fluids.
FLUID_KINDS = ("water", "air")
#: Standard atmospheric pressure [Pa], the default initial (absolute) pressure of the gas.
P0_DEFAULT = 101325.0
#: Polytropic exponents accepted: 1 (isothermal, a slow inflation) to 5/3 (adiabatic monatomic gas);
#: 1.4 is adiabatic air (a snap that lasts milliseconds).
GAMMA_RANGE = (1.0, 5.0 / 3.0)

#: The keys of the setting and what each expects.
FLUID_KEYS = {
    "kind": "'water' or 'air'",
    "V0_ml": "the initial gas volume of syringe, tube and cavity in mL (a number > 0)",
    "gamma": f"the polytropic exponent, a number in [{GAMMA_RANGE[0]:g}, {GAMMA_RANGE[1]:.4g}] (1: isothermal, 1.4: adiabatic air)",
    "p0": "the initial absolute gas pressure in Pa (a number > 0)",
}


@dataclass(frozen=True)
class FluidSettings:
    """What inflates the actuator.

    Parameters
    ----------
    kind : ``"water"`` (incompressible: the cavity volume is controlled; the default) or ``"air"``
        (a gas in series: the syringe's dispensed volume is controlled)
    V0_ml : with air, the gas volume of syringe, tube and cavity before inflation [mL] (paper S3's
        ``V0_sys``); ``None`` with water
    gamma : polytropic exponent of the gas (1 isothermal, eq 8; 1.4 adiabatic air)
    p0 : absolute pressure of the gas before inflation [Pa] (the atmosphere; pressures reported
        are gauge pressures)

    Raises
    ------
    SettingsError
        A value out of its range (the message names the field).
    """

    kind: str = "water"
    V0_ml: float | None = None
    gamma: float = 1.0
    p0: float = P0_DEFAULT

    def __post_init__(self) -> None:
        if self.kind not in FLUID_KINDS:
            raise SettingsError("kind", FLUID_KEYS["kind"], self.kind)
        if self.kind == "water":
            if self.V0_ml is not None or self.gamma != 1.0 or self.p0 != P0_DEFAULT:
                raise SettingsError("kind", "'air' with V0_ml, gamma or p0 (water takes none of them)", self.kind)
            return
        if not _is_number(self.V0_ml) or not self.V0_ml > 0:
            raise SettingsError("V0_ml", FLUID_KEYS["V0_ml"], self.V0_ml)
        if not _is_number(self.gamma) or not GAMMA_RANGE[0] <= self.gamma <= GAMMA_RANGE[1]:
            raise SettingsError("gamma", FLUID_KEYS["gamma"], self.gamma)
        if not _is_number(self.p0) or not self.p0 > 0:
            raise SettingsError("p0", FLUID_KEYS["p0"], self.p0)

    @property
    def is_air(self) -> bool:
        return self.kind == "air"

    @property
    def V0_m3(self) -> float | None:
        """The initial gas volume [m^3] (``None`` with water)."""
        return None if self.V0_ml is None else self.V0_ml * 1e-6

    def as_dict(self) -> dict:
        """The setting as the YAML writes it (``{kind: water}`` or ``{kind: air, V0_ml, gamma, p0}``)."""
        if not self.is_air:
            return {"kind": "water"}
        return {"kind": "air", "V0_ml": float(self.V0_ml), "gamma": float(self.gamma), "p0": float(self.p0)}

    def gas(self) -> "GasLaw | None":
        """The gas law in SI units (``None`` with water)."""
        return GasLaw(self.V0_m3, self.p0, self.gamma) if self.is_air else None


#: The default fluid.
WATER = FluidSettings()


def _is_number(v: object) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def fluid_from_mapping(value: object, number=None) -> FluidSettings:
    """A :class:`FluidSettings` from the YAML form: ``water``, ``air`` is refused (it needs V0_ml),
    or a mapping ``{kind, V0_ml, gamma, p0}`` (``kind`` defaults to ``air`` when ``V0_ml`` is given).

    Parameters
    ----------
    value : the YAML value
    number : optional converter ``number(key, value) -> float`` for the numeric fields (the YAML
        checker, which accepts numbers written as strings and names the key path on error)

    Raises
    ------
    SettingsError
        ``field`` names the offending key (``"kind"`` for a wrong type of the whole value).
    """
    if isinstance(value, str):
        value = {"kind": value}
    if not isinstance(value, dict):
        raise SettingsError("kind", "'water' or a mapping {kind, V0_ml, gamma, p0}", value)
    unknown = [k for k in value if k not in FLUID_KEYS]
    if unknown:
        raise SettingsError(str(unknown[0]), "no other keys than " + ", ".join(FLUID_KEYS), "an unknown key")
    kw = dict(value)
    kw.setdefault("kind", "air" if "V0_ml" in kw else "water")
    for k in ("V0_ml", "gamma", "p0"):
        if k in kw and number is not None:
            kw[k] = number(k, kw[k])
    if kw["kind"] == "air" and "V0_ml" not in kw:
        raise SettingsError("V0_ml", FLUID_KEYS["V0_ml"], None)
    try:
        return FluidSettings(**kw)
    except TypeError as e:  # pragma: no cover - the keys were checked above
        raise SettingsError("kind", "a mapping {kind, V0_ml, gamma, p0}", value) from e


@dataclass(frozen=True)
class GasLaw:
    """A polytropic gas of volume ``V0`` at absolute pressure ``p0`` when the gauge pressure is 0,
    ``(p0 + p) V_gas^gamma = p0 V0^gamma``. Any consistent units (SI, or the solver's scaled ones:
    :meth:`scaled`); ``p`` is the gauge pressure, ``p > -p0``. Functions accept arrays.
    """

    V0: float
    p0: float
    gamma: float = 1.0

    def scaled(self, L: float, S: float) -> "GasLaw":
        """The same gas in units of volume ``L^3`` and of pressure ``S``."""
        return GasLaw(self.V0 / L**3, self.p0 / S, self.gamma)

    def _log(self, p):
        return np.log1p(np.asarray(p, dtype=float) / self.p0)

    def volume(self, p):
        """``V_gas(p) = V0 (p0 / (p0 + p))^(1/gamma)``."""
        return self.V0 * np.exp(-self._log(p) / self.gamma)

    def expelled(self, p):
        """``V0 - V_gas(p)``: how far the gas is compressed; the dispensed volume is
        ``V_d = (V - V_cav0) + expelled(p)`` (eq 9), exact also where it is small."""
        return -self.V0 * np.expm1(-self._log(p) / self.gamma)

    def compliance(self, p):
        """``-dV_gas/dp = V_gas / (gamma (p0 + p))`` (> 0): the gas is a spring of stiffness
        ``1 / compliance`` in series with the actuator."""
        return self.volume(p) / (self.gamma * (self.p0 + np.asarray(p, dtype=float)))

    def energy(self, p):
        """The energy stored in the gas at gauge pressure ``p``, counted from ``p = 0``:
        ``G = integral_0^p q compliance(q) dq``, the work of the gauge pressure (the atmosphere
        outside pays the rest, ``p0`` times the volume change). Isothermal (``gamma = 1``):
        ``p0 V0 (ln(1 + x) - x / (1 + x))``, ``x = p / p0``; polytropic:
        ``p0 V0 [((1 + x)^((gamma - 1)/gamma) - 1) / (gamma - 1) - (1 - (1 + x)^(-1/gamma))]``.
        Written with ``log1p`` / ``expm1``: ``G ~ compliance p^2 / 2`` at small ``x`` without
        cancellation."""
        lg = self._log(p)
        g = self.gamma
        if g == 1.0:
            x = np.asarray(p, dtype=float) / self.p0
            return self.p0 * self.V0 * (lg - x / (1.0 + x))
        return self.p0 * self.V0 * (np.expm1((g - 1.0) / g * lg) / (g - 1.0) + np.expm1(-lg / g))
