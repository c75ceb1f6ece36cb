"""report.html: one self-contained page per results folder (sweep, replay or study).

Tables of the numbers and the folder's PNG figures embedded as base64 data URIs, styles
inline, no script and no reference to anything outside the file, so it opens the same
offline, from an e-mail attachment, or years later. Written next to metrics.json.
"""
from __future__ import annotations

import base64
import html
import math
from pathlib import Path
from typing import Any, Iterable, Sequence

CSS = """
body{font-family:system-ui,-apple-system,'Segoe UI',sans-serif;margin:1.5em auto;max-width:980px;color:#222;
padding:0 1em}
h1{font-size:1.4em} h2{font-size:1.15em;margin-top:1.6em;border-bottom:1px solid #ccc}
table{border-collapse:collapse;margin:.5em 0;font-size:.9em;display:block;overflow-x:auto} td,th{border:1px solid #ccc;padding:.2em .5em}
th{background:#f2f2f2;text-align:left} td.n{text-align:right;font-variant-numeric:tabular-nums}
.holds{color:#1a7f37}.differs{color:#b42318;font-weight:600} figure{margin:1em 0}
img{max-width:100%;height:auto;border:1px solid #eee} figcaption{font-size:.85em;color:#555}
code{background:#f6f6f6;padding:0 .2em}
"""


def _cell(value: Any) -> str:
    if isinstance(value, bool):
        return f"<td>{'yes' if value else 'no'}</td>"
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        if isinstance(value, float):
            text = "-" if not math.isfinite(value) else f"{value:.4g}"
        else:
            text = str(value)
        return f'<td class="n">{text}</td>'
    return f"<td>{html.escape(str(value))}</td>"


def table(header: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    """An HTML table; numbers right-aligned with 4 significant digits."""
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(_cell(v) for v in row) + "</tr>" for row in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def figure(path: Path, caption: str) -> str:
    """A PNG embedded as a data URI (nothing outside the page is referenced)."""
    data = base64.b64encode(Path(path).read_bytes()).decode("ascii")
    alt = html.escape(caption, quote=True)
    return (f'<figure><img alt="{alt}" src="data:image/png;base64,{data}">'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>")


def _provenance(prov: dict | None) -> str:
    if not prov:
        return ""
    rows = [(k.replace("_", " "), "-" if v is None else v) for k, v in prov.items()]
    return "<h2>Provenance</h2>" + table(["", ""], rows)


def page(title: str, sections: Sequence[str]) -> str:
    return ("<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{html.escape(title)}</title><style>{CSS}</style></head><body>"
            f"<h1>{html.escape(title)}</h1>{''.join(sections)}</body></html>\n")


SWEEP_FIGURES = (("rmse_vs_count.png", "RMSE (solid) and sqrt(PCRB) (dashed) vs Starlink count"),
                 ("rmse_vs_time.png", "RMSE vs time at the largest count"),
                 ("trajectories.png", "trial-0 trajectory and its errors"),
                 ("visibility.png", "visible satellites (sky plot and count)"))


def write_sweep_report(out_dir: Path, metrics: dict, figures: bool = True) -> Path:
    """report.html of a sweep folder from its metrics.json content and (with `figures`) its PNG figures."""
    out_dir = Path(out_dir)
    sc = metrics["scenario"]
    title = f"leonav sweep: {sc['name']}"
    intro = (f"<p>{html.escape(str(sc.get('source', '')))}: {sc['duration_s']:g} s from "
             f"{html.escape(str(sc['epoch_utc']))}, {sc['trials']} trials per point, modes "
             f"{html.escape(', '.join(sc['modes']))}, Starlink counts {html.escape(str(sc['counts']))}.</p>")
    rows = []
    for r in metrics["results"]:
        p, v, a = r["position"], r["velocity"], r["attitude_deg"]
        rows.append([r["mode"], r["count"], p["rmse"], p["sqrt_pcrb"], p["final_rmse"], v["rmse"], v["sqrt_pcrb"],
                     a["rmse"], a["sqrt_pcrb"], r["nees"]["mean"], r["gated"], r["failed"]])
    results = "<h2>Results</h2>" + table(
        ["mode", "count", "pos RMSE [m]", "pos sqrt(PCRB) [m]", "pos final RMSE [m]", "vel RMSE [m/s]",
         "vel sqrt(PCRB) [m/s]", "att RMSE [deg]", "att sqrt(PCRB) [deg]", "NEES mean [-]", "gated", "failed"], rows)
    find_rows = []
    for f in metrics["findings"]:
        mark = '<span class="holds">holds</span>' if f["holds"] else '<span class="differs">differs</span>'
        values = "; ".join(f"{v['mode']} @ {v['count']}: {v['position_rmse_time_avg_m']:.2f} m "
                           f"(final {v['position_rmse_final_m']:.2f} m)" for v in f.get("values") or [])
        band = f.get("paper_band_m")
        find_rows.append((f.get("kind", "paper"), f["finding"], mark, f"{band[0]:g}-{band[1]:g} m" if band else "",
                          values or str(f["detail"])))
    head = "".join(f"<th>{h}</th>" for h in ("from", "finding", "", "paper", "ours: time-averaged (final epoch)"))
    body = "".join("<tr>" + "".join(f"<td>{c if i == 2 else html.escape(c)}</td>" for i, c in enumerate(row))
                   + "</tr>" for row in find_rows)
    findings = f"<h2>Findings</h2><table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"
    figs = "".join(figure(out_dir / name, cap) for name, cap in SWEEP_FIGURES
                   if figures and (out_dir / name).is_file())
    notes = "".join(f"<li>{html.escape(str(n))}</li>" for n in metrics.get("notes") or [])
    sections = [intro, results, findings, ("<h2>Figures</h2>" + figs) if figs else "",
                f"<h2>Notes</h2><ul>{notes}</ul>" if notes else "", _provenance(metrics.get("provenance"))]
    path = out_dir / "report.html"
    path.write_text(page(title, sections), encoding="utf-8")
    return path


def write_replay_report(out_dir: Path, metrics: dict) -> Path:
    """report.html of a replay folder from its metrics and PNG figures (beacons/ included)."""
    out_dir = Path(out_dir)
    title = f"leonav replay: {Path(str(metrics['session'])).name}"
    rows = []
    for mode, m in metrics["modes"].items():
        r = m.get("records", {})
        rows.append([mode, m.get("rmse_position_m"), m.get("rmse_velocity_mps"), m.get("rmse_attitude_deg"),
                     r.get("applied", ""), r.get("gated", ""), r.get("failed", "")])
    modes = "<h2>Modes</h2>" + table(["mode", "position RMSE [m]", "velocity RMSE [m/s]", "attitude RMSE [deg]",
                                      "applied", "gated", "failed"],
                                     [[("-" if v is None else v) for v in row] for row in rows])
    skipped = "".join(f"<li>{html.escape(k)}: {html.escape(str(v))}</li>" for k, v in metrics["skipped_modes"].items())
    counts = metrics.get("beacons", {}).get("counts") or {}
    beacons = ("<h2>Beacons</h2>" + table(["", ""], list(counts.items()))) if counts else ""
    figs = "".join(figure(out_dir / name, cap) for name, cap in (
        ("rmse_vs_time.png", "error vs time"), ("trajectories.png", "trajectories"),
        ("beacons/waterfall.png", "beacon waterfall")) if (out_dir / name).is_file())
    notes = "".join(f"<li>{html.escape(str(n))}</li>" for n in metrics.get("notes") or [])
    sections = [f"<p>reference: {html.escape(str(metrics.get('reference') or 'none'))}</p>", modes,
                f"<ul>{skipped}</ul>" if skipped else "", beacons, ("<h2>Figures</h2>" + figs) if figs else "",
                f"<h2>Notes</h2><ul>{notes}</ul>" if notes else "", _provenance(metrics.get("provenance"))]
    path = out_dir / "report.html"
    path.write_text(page(title, sections), encoding="utf-8")
    return path


def write_study_report(out_dir: Path, meta: dict) -> Path:
    """report.html of a study folder from its study.json content and study.png."""
    out_dir = Path(out_dir)
    axes = meta["axes"]
    keys = [a["key"] for a in axes]
    set_text = ", ".join(f"{k} = {v}" for k, v in (meta.get("set") or {}).items()) or "none"
    intro = (f"<p>{html.escape(str(meta.get('description') or ''))}</p><p>base scenario "
             f"<code>{html.escape(str(meta['base_scenario']))}</code>, modes {html.escape(', '.join(meta['modes']))}, "
             f"{meta['trials_per_cell']} trials per cell and mode; fixed: {html.escape(set_text)}; varied: "
             + "; ".join(f"<code>{html.escape(a['key'])}</code> = {html.escape(', '.join(map(str, a['values'])))}"
                         for a in axes) + ".</p>")
    metrics = (("position_rmse_m", "pos RMSE [m]"), ("position_sqrt_pcrb_m", "pos sqrt(PCRB) [m]"),
               ("position_final_rmse_m", "pos final RMSE [m]"), ("position_final_sqrt_pcrb_m", "pos final sqrt(PCRB) [m]"),
               ("velocity_rmse_mps", "vel RMSE [m/s]"), ("attitude_rmse_deg", "att RMSE [deg]"),
               ("nees_mean", "NEES mean [-]"), ("nees_lo", "NEES 95 % low"), ("nees_hi", "NEES 95 % high"))
    rows = [[c["values"][k] for k in keys] + [c["mode"], c["count"]] + [c.get(m, float("nan")) for m, _ in metrics]
            for c in meta["cells"]]
    results = "<h2>Results</h2>" + table(keys + ["mode", "count"] + [h for _, h in metrics], rows)
    figs = figure(out_dir / "study.png", "position RMSE / sqrt(PCRB) and NEES over the study's grid") \
        if (out_dir / "study.png").is_file() else ""
    t = meta.get("timing") or {}
    timing = (f"<p>{t.get('trials_run', '?')} trials in {t.get('wall_s', float('nan')):.1f} s wall "
              f"({html.escape(str(t.get('executor', '')))}).</p>") if t else ""
    sections = [intro, results, ("<h2>Figure</h2>" + figs) if figs else "", timing,
                _provenance(meta.get("provenance"))]
    path = out_dir / "report.html"
    path.write_text(page(f"leonav study: {meta['name']}", sections), encoding="utf-8")
    return path
