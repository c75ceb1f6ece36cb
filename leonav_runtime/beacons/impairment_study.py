"""Association under capture impairments: synthetic captures through the beacon pipeline.

For each impairment set (none, each one alone, all together) and C/N0, `run` writes
synthetic cu8 captures of five satellites from real element sets (`synth`), runs the
pipeline on them (`pipeline.process_capture`) and scores every ridge against the truth:
a ridge is a satellite's if its frequency stays within `MATCH_HZ` of one of that
satellite's true tones (central tone +/- k comb spacings) over its track, else it is not
a satellite's (DC spike, interferer, IQ image, noise). A ridge is *correct* when it is
associated with its own satellite, or is not a satellite's and is not associated;
*wrong* when associated with another satellite (or associated while not a satellite's);
*missed* when it is a satellite's and left unassociated or ambiguous. |delta alpha| is
the post-fit rate residual of the associated ridges (measured minus predicted, Hz/s).
"""
from __future__ import annotations

import dataclasses
import datetime as _dt
import tempfile
import warnings
from pathlib import Path

import numpy as np

from leonav_runtime.beacons import pipeline, synth
from leonav_runtime.beacons.comb import COMB_SPACING_HZ
from leonav_runtime.beacons.impairments import SETS

MATCH_HZ = 300.0


@dataclasses.dataclass
class Score:
    ridges: int = 0
    correct: int = 0
    wrong: int = 0
    missed: int = 0
    satellites: int = 0
    satellites_found: int = 0
    residuals: list = dataclasses.field(default_factory=list)

    def add(self, other: "Score") -> None:
        for f in ("ridges", "correct", "wrong", "missed", "satellites", "satellites_found"):
            setattr(self, f, getattr(self, f) + getattr(other, f))
        self.residuals += other.residuals

    def row(self) -> dict:
        r = np.concatenate(self.residuals) if self.residuals else np.array([np.nan])
        return {"ridges": self.ridges, "correct": self.correct, "wrong": self.wrong, "missed": self.missed,
                "correct_fraction": self.correct / max(self.ridges, 1),
                "satellites_found_fraction": self.satellites_found / max(self.satellites, 1),
                "median_abs_dalpha_hz_s": float(np.nanmedian(np.abs(r))),
                "p90_abs_dalpha_hz_s": float(np.nanpercentile(np.abs(r), 90))}


def ridge_owner(ridge, truth: synth.SynthTruth, tones: int) -> int:
    """NORAD id of the satellite whose true tone the ridge follows, or -1."""
    offsets = (np.arange(-4, 5)) * COMB_SPACING_HZ if tones > 1 else np.zeros(1)
    best, owner = np.inf, -1
    for i, nid in enumerate(truth.norad_ids):
        f_true = np.interp(ridge.t_s, truth.t_grid_s, truth.baseband_hz[i])
        err = np.median(np.abs(ridge.f_hz[None, :] - (f_true[None, :] + offsets[:, None])), axis=1).min()
        if err < best:
            best, owner = err, int(nid)
    return owner if best < MATCH_HZ else -1


def score(res: pipeline.PipelineResult, truth: synth.SynthTruth, tones: int) -> Score:
    s = Score(satellites=len(truth.norad_ids))
    by_id = {a.ridge_id: a for a in res.associations}
    found = set()
    for ridge in res.ridges:
        a = by_id.get(ridge.ridge_id)
        owner = ridge_owner(ridge, truth, tones)
        got = a.norad_id if a is not None and a.status == "associated" else -1
        s.ridges += 1
        if got >= 0 and got == owner:
            s.correct += 1
            found.add(owner)
            if a.rate_residual_hz_s is not None and a.carrier:
                s.residuals.append(np.asarray(a.rate_residual_hz_s, float))
        elif got >= 0:
            s.wrong += 1
        elif owner < 0:
            s.correct += 1
        else:
            s.missed += 1
    s.satellites_found = len(found)
    return s


def one_capture(elements, site, start: _dt.datetime, seed: int, cn0: float, name: str,
                work: Path, duration_s: float = 6.0, fs: float = 400e3) -> Score:
    imp, extra = SETS[name]
    cfg = synth.SynthConfig(duration_s=duration_s, sample_rate_hz=fs, cn0_dbhz=cn0, seed=seed,
                            lo_offset_hz=float(np.random.default_rng(seed).uniform(-30e3, 30e3)),
                            impairments=imp, **extra)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # stale-element warnings of the real sets: same for every set
        info, truth = synth.write_synthetic_capture(work / f"c{seed}.cu8", elements, site, start, cfg)
        res = pipeline.process_capture(info, elements, site, pipeline.PipelineConfig(band_hz=fs))
    return score(res, truth, cfg.tones_per_satellite)


def run(elements, site, start: _dt.datetime, names: list[str], cn0s: list[float], trials: int,
        progress=None, duration_s: float = 6.0) -> list[dict]:
    """Rows (impairment set, C/N0, counts, fractions, |delta alpha|) over `trials` captures,
    each starting 37 min after the previous (different sky, different satellites)."""
    rows = []
    with tempfile.TemporaryDirectory(prefix="leonav-impair-") as tmp:
        for name in names:
            for cn0 in cn0s:
                total = Score()
                for seed in range(trials):
                    t0 = start + _dt.timedelta(minutes=37 * seed)
                    total.add(one_capture(elements, site, t0, seed, cn0, name, Path(tmp), duration_s))
                    if progress:
                        progress()
                rows.append({"impairments": name, "cn0_dbhz": cn0, "trials": trials, **total.row()})
    return rows


def write_results(out_dir: Path, rows: list[dict], meta: dict) -> None:
    """impairments.csv, impairments.json and impairments.png (correct fraction, |delta alpha|)."""
    from leonav_runtime.common import output, plot_style

    plt = plot_style.pyplot(style=False)   # matplotlib's default look; a notebook keeps its backend

    out_dir = Path(out_dir)
    keys = list(rows[0])
    output.write_csv(out_dir / "impairments.csv", keys, [[r[k] for k in keys] for r in rows])
    from leonav_runtime.common.provenance import provenance

    output.write_json(out_dir / "impairments.json", {"provenance": provenance(), **meta, "sets": {n: {"impairments": dataclasses.asdict(i)
                                                                          if i else None, "synth": e}
                                                                      for n, (i, e) in SETS.items()}, "rows": rows})
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(13, 4.5))
    cn0s = sorted({r["cn0_dbhz"] for r in rows})
    names = list(dict.fromkeys(r["impairments"] for r in rows))
    width = 0.8 / len(cn0s)
    for j, cn0 in enumerate(cn0s):
        sel = {r["impairments"]: r for r in rows if r["cn0_dbhz"] == cn0}
        x = np.arange(len(names)) + j * width
        a1.bar(x, [100 * sel[n]["correct_fraction"] for n in names], width, label=f"{cn0:g} dB-Hz")
        a2.bar(x, [sel[n]["median_abs_dalpha_hz_s"] for n in names], width, label=f"{cn0:g} dB-Hz")
    for a in (a1, a2):
        a.set_xticks(np.arange(len(names)) + 0.4 - width / 2, names, rotation=35, ha="right", fontsize=8)
        a.grid(True, axis="y", alpha=0.3)
        a.legend(fontsize=8)
    a1.axhline(90, color="k", lw=0.8, ls="--")
    a1.set_ylabel("ridges scored correct (%)")
    a2.set_ylabel("median |delta alpha| of associated ridges (Hz/s)")
    fig.suptitle(f"beacon association under capture impairments ({rows[0]['trials']} captures per bar)")
    fig.tight_layout()
    fig.savefig(out_dir / "impairments.png", dpi=110)
    plt.close(fig)
