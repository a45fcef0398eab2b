"""``snapjump curve`` gives the jump (the model ``rank`` applies to a row), draws it (``--jump``),
carries its inputs and version in the JSON, and draws every figure as .png, .svg or .pdf in
physical units (``--normalised``: the paper's axes)."""
from __future__ import annotations

import json

import pytest

from snapjump_cli.commands.curve import JUMP_KEYS, main

DESIGN_C = ["--design", "C"]


@pytest.fixture(scope="module")
def design_c(tmp_path_factory):
    from click.testing import CliRunner

    from snapjump_cli.cli import cli

    out = tmp_path_factory.mktemp("jump")
    files = {"jump": out / "j.svg", "plot": out / "c.pdf", "shapes": out / "s.svg"}
    r = CliRunner().invoke(cli, ["curve", *DESIGN_C, "--format", "json", "--jump", str(files["jump"]),
                                 "--plot", str(files["plot"]), "--shapes", str(files["shapes"])])
    assert r.exit_code == 0, r.output
    text = CliRunner().invoke(cli, ["curve", *DESIGN_C])
    assert text.exit_code == 0, text.output
    return json.loads(r.stdout), files, text.stdout


def test_jump_keys_are_ranks(design_c):
    """y_jump_m and the flags are those ``snapjump rank`` gives the same row."""
    pd = pytest.importorskip("pandas")
    from snapjump_cli.jump.rank import rank_results

    m, _, _ = design_c
    assert all(k in m for k in JUMP_KEYS)
    assert m["y_jump_m"] > m["h_imp_m"] and m["jumped"] is True and m["lift_off"] is True
    row = {"status": "ok", "R_i": 0.03, **{k: m[k] for k in ("dE_J", "dy_pole_m", "h_imp_m", "V_inner_solid_m3",
                                                            "V_outer_solid_m3")}}
    ranked = rank_results(pd.DataFrame([row]))
    for k in ("y_jump_m", "t_peak_s", "m_i_kg", "m_o_kg", "k_s", "jump_rise_m", "y_jump_norm"):
        assert m[k] == pytest.approx(float(ranked[k].iloc[0]), rel=1e-12), k
    for k in ("n_contacts", "jumped", "lift_off", "jump_complete"):
        assert m[k] == ranked[k].iloc[0], k
    assert m["jump_reason"] == ranked["jump_reason"].iloc[0]


def test_json_provenance(design_c):
    m, _, _ = design_c
    inp = m["inputs"]
    assert inp["scene"]["eta_i"] > 0 and inp["scene"]["kind"] == "design"
    assert inp["mesh"]["order"] in (1, 2) and "nt" in inp["mesh"]
    assert inp["solver"]["tol"] > 0 and inp["solver"]["harmonics"] == 0
    assert inp["jump"]["rho"] == 1000.0
    assert m["snapjump_version"]


def test_text_has_the_jump(design_c):
    m, _, text = design_c
    line = next(x for x in text.splitlines() if x.startswith("jump "))
    assert f"{m['y_jump_m'] * 1e3:.5g} mm" in line and "lifts off" in line


def test_figures_in_every_format(design_c):
    m, files, _ = design_c
    assert files["plot"].read_bytes()[:5] == b"%PDF-"
    for k in ("jump", "shapes"):
        head = files[k].read_text()[:400]
        assert "<svg" in head, k
    svg = files["jump"].read_text()
    assert "lift-off" in svg and "apex" in svg and "y_jump" in svg


def test_plot_units(tmp_path, monkeypatch):
    """The p-V plot is in kPa and ml by default, on the paper's axes with --normalised."""
    from snapjump_cli.viz import figures

    seen = []
    save = figures._save

    def keep(fig, path, dpi):
        ax = fig.axes[0]
        seen.append((ax.get_xlabel(), ax.get_ylabel(), ax.get_xlim()))
        return save(fig, path, dpi)

    monkeypatch.setattr(figures, "_save", keep)
    cap = ["--cap", "--theta", "60", "--eta", "8.5", "--bc", "roller-point"]
    assert main([*cap, "--plot", str(tmp_path / "a.png")]) == 0
    assert main([*cap, "--plot", str(tmp_path / "b.png"), "--normalised"]) == 0
    (xa, ya, _), (xb, yb, _) = seen
    assert "[ml]" in xa and "[kPa]" in ya
    assert "R_i^3" in xb and "mu_i" in yb


def test_jump_without_a_snap_is_an_error(tmp_path, capsys):
    """A scene that does not snap has no jump to draw: one line, nothing written."""
    out = tmp_path / "j.png"
    rc = main(["--cap", "outer", "--theta", "90", "--eta", "16.5", "--jump", str(out)])
    err = capsys.readouterr().err
    assert rc != 0 and "--jump" in err and not out.exists()
