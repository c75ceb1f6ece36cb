"""RINEX reading and broadcast-orbit speed: leonav's readers against georinex (if installed), and
the cost of reading the same files compressed (gzip, unix compress, Hatanaka + gzip).

    python benchmarks/bench_rinex.py [--repeat N]

Reads the shared GEONET/IGS files (../shared/data, see SOURCES.md), a 24-hour RINEX 2
observation file made here by repeating the 0759 hour (2880 epochs), and times
`satellite_states` over a day of 30-s epochs for every GPS satellite. CPU seconds
(time.process_time; the Hatanaka decoder is a child process, its CPU from getrusage of the
children), best of N, read side by side in one run; ratios printed. The load average is
printed before and after.
"""
from __future__ import annotations

import argparse
import gzip
import os
import resource
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from leonav_runtime.gnss.rinex_nav import read_rinex_nav  # noqa: E402
from leonav_runtime.gnss.rinex_obs import read_rinex_obs  # noqa: E402
from leonav_runtime.orbits.broadcast import satellite_states  # noqa: E402

DATA = Path(os.environ.get("LEONAV_SHARED_DATA", ROOT.parent / "shared" / "data"))


def _cpu() -> float:
    """CPU s of this process and of its finished children (crx2rnx)."""
    c = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + c.ru_utime + c.ru_stime


def best(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t = _cpu()
        fn()
        times.append(_cpu() - t)
    return min(times)


def day_obs_file(tmp: Path) -> Path:
    """24 h of 30-s epochs: the 0759 hour repeated with shifted epoch times."""
    lines = (DATA / "gnss_rinex" / "07590920.05o").read_text().splitlines()
    end = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    head, body = lines[:end], lines[end:]
    out = list(head)
    for hour in range(24):
        for ln in body:
            if ln.startswith(" 05  4  2  0 "):
                ln = ln[:10] + f"{hour:2d}" + ln[12:]
            out.append(ln)
    path = tmp / "day.05o"
    path.write_text("\n".join(out) + "\n")
    return path


def compressed(path: Path, tmp: Path) -> dict[str, Path]:
    """{kind: path} of compressed copies (those whose package is installed)."""
    raw = path.read_bytes()
    out = {"gz": tmp / (path.name + ".gz")}
    out["gz"].write_bytes(gzip.compress(raw))
    try:
        import ncompress

        out["Z"] = tmp / (path.name + ".Z")
        out["Z"].write_bytes(ncompress.compress(raw))
    except ImportError:
        pass
    try:
        import hatanaka

        out["YYd.gz"] = tmp / (path.name[:-1] + "d.gz")
        out["YYd.gz"].write_bytes(gzip.compress(hatanaka.rnx2crx(raw)))
    except ImportError:
        pass
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    try:
        import georinex
    except ImportError:
        georinex = None
    print("load average before: {:.2f} {:.2f} {:.2f}".format(*os.getloadavg()))
    nav = DATA / "tle" / "rtklib_gnss_20121031" / "brdc3050.12n"
    obs = DATA / "gnss_rinex" / "07590920.05o"
    with tempfile.TemporaryDirectory() as tmp:
        day = day_obs_file(Path(tmp))
        cases = [("nav brdc3050.12n (423 records)", nav, read_rinex_nav),
                 ("obs 07590920.05o (120 epochs)", obs, read_rinex_obs),
                 ("obs 24 h (2880 epochs)", day, read_rinex_obs)]
        print(f"{'case':<34} {'leonav CPU s':>12} {'georinex CPU s':>14} {'ratio':>6}")
        for label, path, reader in cases:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                ours = best(lambda reader=reader, path=path: reader(path), args.repeat)
                theirs = best(lambda path=path: georinex.load(path), args.repeat) if georinex else float("nan")
            print(f"{label:<34} {ours:>12.4f} {theirs:>14.4f} {theirs / ours:>6.1f}")
        print(f"\n{'the same files compressed':<34} {'CPU s':>12} {'/ plain':>14}")
        for label, path, reader in cases[1:]:
            plain = best(lambda reader=reader, path=path: reader(path), args.repeat)
            for kind, cpath in compressed(path, Path(tmp)).items():
                t = best(lambda reader=reader, cpath=cpath: reader(cpath), args.repeat)
                print(f"{label + ' .' + kind:<34} {t:>12.4f} {t / plain:>13.2f}x")
    eph = read_rinex_nav(nav).ephemerides
    t = float(np.min(eph["toe"])) + np.arange(0, 86400, 30.0)
    prns = np.repeat(np.arange(1, 33), t.size)
    tt = np.tile(t, 32)
    sel = best(lambda: eph.select("G", prns, tt), args.repeat)
    idx, st = eph.select("G", prns, tt)
    ok = st == 0
    rows, tok = eph.data[idx[ok]], tt[ok]
    orb = best(lambda: satellite_states(rows, tok), args.repeat)
    print(f"\nselect, 32 sats x 2880 epochs: {sel:.3f} s CPU; satellite_states for {ok.sum()} (sat, epoch): "
          f"{orb:.3f} s CPU ({orb / ok.sum() * 1e6:.2f} us each)")
    print("load average after: {:.2f} {:.2f} {:.2f}".format(*os.getloadavg()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
