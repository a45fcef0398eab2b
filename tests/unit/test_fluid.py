"""The fluid setting (snapjump_cli/fe/fluid.py): the gas law, the shared checks of the YAML and the
command line, and how the setting enters the sweep's keys and rows."""
from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.integrate import quad

from snapjump_cli.sweep.config import ConfigError, parse_config
from snapjump_cli.fe.axisym.fluid import WATER, FluidSettings, GasLaw, fluid_from_mapping
from snapjump_cli.settings import MeshSettings, SettingsError, SolverSettings
from snapjump_cli.sweep.storage import design_key
from snapjump_cli.sweep.run import _row_settings

GRID = {"eta_i": [6], "theta_i": [80], "eta_o": [12], "theta_o": [82], "mu_ratio": [5.8]}


@pytest.mark.parametrize("gamma", [1.0, 1.4, 5 / 3])
@pytest.mark.parametrize("p", [1.0, 3e3, 3e4, 2e5])
def test_gas_law(gamma, p):
    """V_gas from the polytropic law; compliance = -dV_gas/dp (finite differences); the energy is
    the integral of p dV_expelled (quadrature), without cancellation at small pressures."""
    g = GasLaw(45e-6, 101325.0, gamma)
    P = 101325.0 + p
    assert P * g.volume(p) ** gamma == pytest.approx(101325.0 * 45e-6**gamma, rel=1e-13)
    assert g.expelled(p) == pytest.approx(45e-6 - g.volume(p), rel=1e-12, abs=1e-20)
    h = 1e-4 * p
    fd = (g.volume(p - h) - g.volume(p + h)) / (2 * h)
    assert g.compliance(p) == pytest.approx(fd, rel=1e-7)
    num = quad(lambda q: q * g.compliance(q), 0.0, p, epsabs=0.0, epsrel=1e-13)[0]
    assert g.energy(p) == pytest.approx(num, rel=1e-11)


def test_gas_law_isothermal_is_eq8_and_scales():
    """gamma = 1 is Boyle's law (eq 8); the scaled gas is the same gas in other units."""
    g = GasLaw(45e-6, 1e5, 1.0)
    assert g.volume(2e3) == pytest.approx(45e-6 * 1e5 / 1.02e5, rel=1e-15)
    s = g.scaled(0.03, 0.35e6)
    assert s.volume(2e3 / 0.35e6) * 0.03**3 == pytest.approx(g.volume(2e3), rel=1e-14)
    assert s.energy(2e3 / 0.35e6) * 0.35e6 * 0.03**3 == pytest.approx(g.energy(2e3), rel=1e-12)


def test_settings_checks_are_shared():
    assert FluidSettings() == WATER and not WATER.is_air and WATER.gas() is None
    air = FluidSettings(kind="air", V0_ml=45)
    assert air.V0_m3 == pytest.approx(45e-6) and air.as_dict() == {"kind": "air", "V0_ml": 45.0, "gamma": 1.0,
                                                                   "p0": 101325.0}
    assert fluid_from_mapping(air.as_dict()) == air and fluid_from_mapping("water") == WATER
    assert fluid_from_mapping({"V0_ml": 45}) == air  # V0_ml means air
    for kw, field in (({"kind": "air"}, "V0_ml"), ({"kind": "air", "V0_ml": -1}, "V0_ml"),
                      ({"kind": "air", "V0_ml": 45, "gamma": 0.9}, "gamma"),
                      ({"kind": "air", "V0_ml": 45, "gamma": 2.0}, "gamma"),
                      ({"kind": "air", "V0_ml": 45, "p0": 0}, "p0"), ({"kind": "oil"}, "kind"),
                      ({"kind": "water", "V0_ml": 45}, "kind"), ({"kind": "air", "V0_ml": 45, "T": 1}, "T")):
        with pytest.raises(SettingsError) as e:
            fluid_from_mapping(kw)
        assert e.value.field == field


@pytest.mark.parametrize(
    "fluid,where",
    [
        ("{kind: air}", "fluid.V0_ml"),
        ("{kind: air, V0_ml: 0}", "fluid.V0_ml"),
        ("{kind: air, V0_ml: abc}", "fluid.V0_ml"),
        ("{kind: air, V0_ml: 45, gamma: 3}", "fluid.gamma"),
        ("{kind: air, V0_ml: 45, p0: -1}", "fluid.p0"),
        ("{kind: air, V0_ml: 45, volume: 3}", "fluid.volume"),
        ("{kind: gas, V0_ml: 45}", "fluid.kind"),
        ("oil", "fluid"),
        ("[1, 2]", "fluid"),
    ],
)
def test_yaml_errors_name_the_key(fluid, where):
    import yaml

    doc = {"grid": GRID, "fluid": yaml.safe_load(fluid)}
    with pytest.raises(ConfigError) as e:
        parse_config(doc, "cfg.yaml")
    assert str(e.value).startswith(f"cfg.yaml: {where}: ")
    assert "\n" not in str(e.value)


def test_yaml_air_and_harmonics_refused():
    with pytest.raises(ConfigError, match="solver.harmonics"):
        parse_config({"grid": GRID, "fluid": {"kind": "air", "V0_ml": 45}, "solver": {"harmonics": 2}}, "c.yaml")


def test_water_leaves_keys_rows_and_config_as_they_were():
    """Water (the default, or written out) changes neither the design keys, nor the settings a row
    records, nor the config's provenance; air changes all three."""
    base = parse_config({"grid": GRID})
    water = parse_config({"grid": GRID, "fluid": "water"})
    air = parse_config({"grid": GRID, "fluid": {"kind": "air", "V0_ml": "45", "gamma": 1.4}})
    assert water.fluid == WATER and air.fluid == FluidSettings(kind="air", V0_ml=45.0, gamma=1.4)
    p = next(base.designs())
    m, s = MeshSettings(), SolverSettings()
    assert design_key(p, m, s, WATER) == design_key(p, m, s)
    assert design_key(p, m, s, air.fluid) != design_key(p, m, s)
    assert design_key(p, m, s, air.fluid) != design_key(p, m, s, FluidSettings(kind="air", V0_ml=45.0))
    assert _row_settings(water) == s.numerics() and "fluid" not in water.to_dict()
    assert _row_settings(air)["fluid"] == air.fluid.as_dict() and air.to_dict()["fluid"]["V0_ml"] == 45.0
    json.dumps(air.to_dict())


def test_expelled_volume_is_exact_at_small_pressure():
    g = GasLaw(1.0, 1.0, 1.4)
    x = 1e-12
    assert g.expelled(x) == pytest.approx(x / 1.4, rel=1e-9)
    assert np.isfinite(g.energy(0.0)) and g.energy(0.0) == 0.0
