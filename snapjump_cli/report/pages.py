"""The HTML of the design card and of the sweep report (see the package docstring).

Plain string building with :func:`html.escape` on every value that comes from data; figures are
rendered by the functions of :mod:`snapjump_cli.viz` into a temporary folder and embedded.
"""
from __future__ import annotations

import base64
import html
import tempfile
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

__all__ = ["design_page", "results_page", "figure_png", "STYLE"]

STYLE = """
body{font-family:system-ui,-apple-system,'Segoe UI',Roboto,Helvetica,Arial,sans-serif;margin:2em auto;max-width:1100px;
color:#222;line-height:1.4;padding:0 1em}
h1{font-size:1.6em;margin-bottom:.2em}h2{font-size:1.2em;margin-top:1.6em;border-bottom:1px solid #ddd}
.sub{color:#555;margin-top:0}
table{border-collapse:collapse;font-size:.9em;margin:.5em 0}
td,th{border:1px solid #ddd;padding:.25em .6em;text-align:right}th{background:#f3f3f3;cursor:default}
td.l,th.l{text-align:left}
table.sortable th{cursor:pointer}
.flag{display:inline-block;padding:.05em .5em;border-radius:.8em;font-size:.85em;margin-right:.3em;background:#eee}
.warn{background:#fde2c8}.good{background:#d6f0d6}.bad{background:#f6d0d0}
figure{margin:1em 0}figure img{max-width:min(100%,780px);border:1px solid #eee}figcaption{color:#555;font-size:.9em}
code,pre{background:#f6f6f6;padding:.1em .3em;border-radius:3px;font-size:.9em}pre{padding:.6em;overflow-x:auto}
.grid{display:grid;grid-template-columns:repeat(auto-fit,minmax(420px,1fr));gap:1em}
footer{margin-top:2em;color:#777;font-size:.85em}
"""

#: Sorting a table by a click on a column header: plain JavaScript, in the page.
SORT_JS = """
document.querySelectorAll('table.sortable th').forEach(function(th,i){th.addEventListener('click',function(){
var t=th.closest('table'),b=t.tBodies[0],r=Array.from(b.rows),asc=th.dataset.asc!=='1';th.dataset.asc=asc?'1':'0';
r.sort(function(a,c){var x=a.cells[i].dataset.v||a.cells[i].textContent,y=c.cells[i].dataset.v||c.cells[i].textContent;
var p=parseFloat(x),q=parseFloat(y);if(!isNaN(p)&&!isNaN(q)){return asc?p-q:q-p}return asc?x.localeCompare(y):y.localeCompare(x)});
r.forEach(function(x){b.appendChild(x)})})});
"""

_E = html.escape


def figure_png(draw: Callable[[Path], object], suffix: str = ".png") -> bytes:
    """The bytes of a figure that ``draw(path)`` writes (into a temporary folder)."""
    with tempfile.TemporaryDirectory(prefix="snapjump-report-") as d:
        p = Path(d) / f"figure{suffix}"
        draw(p)
        return p.read_bytes()


def _img(data: bytes | None, caption: str, alt: str) -> str:
    if not data:
        return ""
    uri = "data:image/png;base64," + base64.b64encode(data).decode("ascii")
    return f'<figure><img src="{uri}" alt="{_E(alt)}"><figcaption>{_E(caption)}</figcaption></figure>'


def _fmt(v: Any, scale: float = 1.0, digits: int = 4) -> str:
    if v is None or str(v) in ("<NA>", "nan", "NaT"):
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "no"
    try:
        x = float(v) * scale
    except (TypeError, ValueError):
        return _E(str(v))
    if x != x:
        return "–"
    return f"{x:.{digits}g}"


def _table(rows: Iterable[Sequence[Any]], head: Sequence[str] | None = None, cls: str = "",
           left: Iterable[int] = (0,)) -> str:
    left = set(left)
    out = [f'<table class="{cls}">' if cls else "<table>"]
    if head:
        out.append("<thead><tr>" + "".join(f'<th class="{"l" if i in left else ""}">{_E(h)}</th>'
                                           for i, h in enumerate(head)) + "</tr></thead>")
    out.append("<tbody>")
    for r in rows:
        cells = []
        for i, c in enumerate(r):
            if isinstance(c, tuple):  # (shown html, sort value)
                cells.append(f'<td class="{"l" if i in left else ""}" data-v="{_E(str(c[1]))}">{c[0]}</td>')
            else:
                cells.append(f'<td class="{"l" if i in left else ""}">{c}</td>')
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</tbody></table>")
    return "".join(out)


def _page(title: str, body: str, script: bool = False) -> str:
    js = f"<script>{SORT_JS}</script>" if script else ""
    return (f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><meta name="viewport" '
            f'content="width=device-width,initial-scale=1"><title>{_E(title)}</title><style>{STYLE}</style>'
            f"</head><body>{body}{js}</body></html>\n")


def _flag(text: str, kind: str = "") -> str:
    return f'<span class="flag {kind}">{_E(text)}</span>'


def _footer(version: str | None, git: str | None, command: str | None, created: str) -> str:
    bits = [f"snapjump {_E(version or '?')}" + (f" (git {_E(git)})" if git else ""), f"made {_E(created)}"]
    cmd = f"<p>command: <code>{_E(command)}</code></p>" if command else ""
    return f"<footer>{cmd}<p>{' · '.join(bits)}. A self-contained page: no network is used to view it.</p></footer>"


# ---- the design card -------------------------------------------------------------------------
def design_page(title: str, m: dict, figures: dict[str, bytes | None], command: str | None, created: str) -> str:
    """The design card of one solved scene.

    Parameters
    ----------
    title : the scene (``design D``, ...)
    m : the metrics as ``snapjump curve --format json`` gives them (with the jump keys and ``inputs``)
    figures : PNG bytes of ``pv`` (the p-V curve), ``shapes`` and ``jump`` (``None`` to leave one out)
    command : the command line that made it
    created : the time it was made (ISO 8601)
    """
    flags = []
    if not m.get("snaps"):
        flags.append(_flag("does not snap", "bad"))
    if m.get("followed"):
        flags.append(_flag(f"followed branch n = {m.get('follow_n')}: the snap below is the followed one", "warn"))
    elif m.get("asym_first"):
        flags.append(_flag(f"asymmetric mode n = {m.get('asym_n')} first: this axisymmetric snap does not happen",
                           "bad"))
    elif m.get("asym_first") is False:
        flags.append(_flag("axisymmetric up to V* (harmonics checked)", "good"))
    else:
        flags.append(_flag("asymmetric modes not checked"))
    if m.get("mesh_sensitive"):
        flags.append(_flag("mesh-sensitive snap", "warn"))
    if m.get("self_crossing"):
        flags.append(_flag("self-crossing path", "warn"))
    if m.get("jumped") is True:
        flags.append(_flag("jumps", "good"))
    elif m.get("jumped") is False and m.get("snaps"):
        flags.append(_flag(f"does not jump: {m.get('jump_reason') or ''}", "bad"))
    rows = [
        ("snap pressure p*", _fmt(m.get("p_star_Pa"), 1e-3), "kPa"),
        ("snap volume V*", _fmt(m.get("V_star_m3"), 1e6), "ml"),
        ("released energy ΔE", _fmt(m.get("dE_J"), 1e3), "mJ"),
        ("pole travel Δy_pole", _fmt(m.get("dy_pole_m"), 1e3), "mm"),
        ("pole height at impact h_imp", _fmt(m.get("h_imp_m"), 1e3), "mm"),
        ("jump height y_jump", _fmt(m.get("y_jump_m"), 1e3), "mm"),
        ("time of the apex", _fmt(m.get("t_peak_s"), 1e3), "ms"),
        ("lifts off", _fmt(m.get("lift_off")), ""),
        ("jump simulation complete", _fmt(m.get("jump_complete")), ""),
        ("pressure maximum p_max", _fmt(m.get("p_max_Pa"), 1e-3), "kPa"),
        ("lower state found", _E(str((m.get("follow_lower_method") if m.get("followed") else None)
                                     or m.get("lower_state_method") or "–")), ""),
        ("masses m_i / m_o", f"{_fmt(m.get('m_i_kg'), 1e3)} / {_fmt(m.get('m_o_kg'), 1e3)}", "g"),
        ("followed", _fmt(m.get("followed")) if m.get("followed") is not None else "not asked (--follow)", ""),
    ]
    if m.get("followed"):
        rows += [("axisymmetric ΔE (does not happen)", _fmt(m.get("axisym_dE_J"), 1e3), "mJ"),
                 ("axisymmetric V* (does not happen)", _fmt(m.get("axisym_V_star_m3"), 1e6), "ml"),
                 ("jump with the axisymmetric snap", _fmt(m.get("y_jump_axisym_m"), 1e3), "mm")]
    metrics = _table(((_E(a), b, _E(c)) for a, b, c in rows), ("quantity", "value", "unit"), left=(0, 2))
    inp = m.get("inputs") or {}
    inputs = "".join(f"<h3>{_E(k)}</h3>" + _table(((_E(str(a)), _E(str(b))) for a, b in (v or {}).items()),
                                                  ("name", "value"), left=(0, 1))
                     for k, v in inp.items())
    body = (f"<h1>{_E(title)}</h1><p class=\"sub\">design card: what the actuator does when inflated with water, "
            f"and its jump (the mass-spring model of <code>snapjump rank</code>)</p><p>{''.join(flags)}</p>"
            f"<h2>The snap and the jump</h2>{metrics}"
            f"<h2>Pressure against volume</h2>"
            + _img(figures.get("pv"), "the p-V curve, the snap at fixed volume and the energy it releases (kPa, ml)",
                   "p-V curve")
            + "<h2>States</h2>"
            + _img(figures.get("shapes"), "sections of the states the actuator takes, coloured by the largest "
                                          "principal stretch", "states")
            + "<h2>The jump</h2>"
            + _img(figures.get("jump"), "heights of the two masses against time, lift-off and apex marked", "jump")
            + f"<h2>Inputs</h2>{inputs}"
            + _footer(m.get("snapjump_version"), m.get("git_commit"), command, created))
    return _page(f"snapjump: {title}", body)


# ---- the sweep report ------------------------------------------------------------------------
_RANK_COLS = (("rank", "rank", 1.0), ("eta_i", "η_i", 1.0), ("theta_i_deg", "θ_i [deg]", 1.0), ("eta_o", "η_o", 1.0),
              ("theta_o_deg", "θ_o [deg]", 1.0), ("mu_ratio", "μ_i/μ_o", 1.0), ("y_jump_m", "y_jump [mm]", 1e3),
              ("dE_J", "ΔE [mJ]", 1e3), ("dy_pole_m", "Δy_pole [mm]", 1e3), ("h_imp_m", "h_imp [mm]", 1e3),
              ("p_star_Pa", "p* [kPa]", 1e-3), ("V_star_m3", "V* [ml]", 1e6))
_FLAG_COLS = (("jumped", "jumps"), ("followed", "followed"), ("asym_first", "asymmetric first"),
              ("self_crossing", "self-crossing"), ("mesh_sensitive", "mesh-sensitive"))


def results_page(source: str, ranked, summary: dict, figures: dict[str, bytes | None], top: int, command: str | None,
                 created: str) -> str:
    """The report of a result file.

    Parameters
    ----------
    source : the result file
    ranked : its rows ranked by :func:`snapjump_cli.jump.rank.rank_results` (a pandas DataFrame)
    summary : :func:`snapjump_cli.commands.info.summarise`'s answer (counts, reasons, provenance)
    figures : PNG bytes of ``fig4a``, ``fig4c`` and ``params``
    top : rows of the ranking shown
    command, created : as in :func:`design_page`
    """
    import math

    counts = ", ".join(f"{_E(k)} {v}" for k, v in summary["status_counts"].items())
    head = [h for c, h, _ in _RANK_COLS if c in ranked.columns] + ["flags"]
    rows = []
    for _, r in ranked.head(top).iterrows():
        cells = []
        for c, _h, scale in _RANK_COLS:
            if c not in ranked.columns:
                continue
            v = r[c]
            try:
                x = float(v)
            except (TypeError, ValueError):
                x = math.nan
            cells.append((_fmt(v, scale, 4 if c != "rank" else 6), "" if x != x else x * scale))
        fl = []
        for c, name in _FLAG_COLS:
            if c in ranked.columns:
                v = r[c]
                if v is not None and not (isinstance(v, float) and v != v) and str(v) not in ("<NA>",) and bool(v):
                    fl.append(_flag(name, "good" if c == "jumped" else "warn"))
        if str(r.get("status")) != "ok":
            fl.append(_flag(str(r.get("status")), "bad"))
        cells.append(" ".join(fl))
        rows.append(cells)
    ranking = _table(rows, head, cls="sortable", left=(len(head) - 1,))
    reasons = ""
    if summary["reasons"]:
        reasons = "<h2>Why some designs were not solved</h2>" + _table(
            ((_E(g["status"]), g["count"], _E(g["reason"]), _E(g["example"])) for g in summary["reasons"]),
            ("status", "designs", "reason (numbers as #)", "example"), left=(0, 2, 3))
    cfg = summary.get("config") or {}
    config = _table(((_E(str(k)), f"<code>{_E(str(v))}</code>") for k, v in cfg.items()), ("key", "value"),
                    left=(0, 1)) if cfg else "<p>(no config recorded)</p>"
    best = summary.get("best")
    best_line = ""
    if ranked["y_jump_m"].notna().any():
        b = ranked.iloc[0]
        best_line = (f"<p>Best design: η_i {_fmt(b['eta_i'])}, θ_i {_fmt(b['theta_i_deg'])}°, η_o {_fmt(b['eta_o'])}, "
                     f"θ_o {_fmt(b['theta_o_deg'])}°, μ_i/μ_o {_fmt(b['mu_ratio'])}: jump "
                     f"<b>{_fmt(b['y_jump_m'], 1e3)} mm</b>.</p>")
    del best
    body = (f"<h1>Sweep report</h1><p class=\"sub\">{_E(source)}: {summary['n_rows']} designs ({counts})</p>"
            f"{best_line}<h2>Ranking (top {min(top, len(ranked))}; click a header to sort)</h2>{ranking}"
            f"<h2>Energy against pole travel (Fig. 4A)</h2>"
            + _img(figures.get("fig4a"), "released energy against pole travel of the snapping designs; markers: "
                                         "the flags", "Fig. 4A")
            + "<h2>Jump height (Fig. 4C)</h2>"
            + _img(figures.get("fig4c"), "jump height of the mass-spring model over the same plane", "Fig. 4C")
            + "<h2>Jump height against each parameter</h2>"
            + _img(figures.get("params"), "jump height [mm] against each design parameter", "parameters")
            + reasons
            + f"<h2>Config</h2>{config}"
            + "<h2>Provenance</h2>"
            + _table([(_E(k), _E(str(summary.get(k) or "–"))) for k in
                      ("command", "version", "git", "python", "platform", "created_utc")]
                     + [("hosts", _E(", ".join(summary.get("hosts") or []) or "–"))]
                     + [("mixed settings", _E("; ".join(summary.get("settings_mix") or []) or "none"))],
                     ("", ""), left=(0, 1))
            + _footer(summary.get("version"), summary.get("git"), command, created))
    return _page(f"snapjump: {source}", body, script=True)
