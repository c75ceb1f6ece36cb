"""report.html: self-contained (no reference outside the file) and rendered by a real
headless browser (Debian's chromium; skipped with the reason when it is absent)."""
from __future__ import annotations

import html.parser
import json
import re
import shutil
import subprocess

import pytest

from leonav_runtime.common import html_report
from leonav_runtime.sweep import plots as sweep_plots
from leonav_runtime.sweep.run import run_sweep
from tests.conftest import short_paper_scenario


class _Refs(html.parser.HTMLParser):
    """Every URL-like attribute value and every url(...) in inline CSS."""

    def __init__(self):
        super().__init__()
        self.refs: list[str] = []
        self.tags: list[str] = []

    def handle_starttag(self, tag, attrs):
        self.tags.append(tag)
        for name, value in attrs:
            if name in ("src", "href", "action", "poster", "data", "srcset", "background") and value is not None:
                self.refs.append(value)
            if name == "style" and value:
                self.refs += re.findall(r"url\(([^)]*)\)", value)

    def handle_data(self, data):  # inline <style> text: url(...) and @import reach out too
        self.refs += re.findall(r"url\(([^)]*)\)", data) + re.findall(r"@import\s+([^;]+)", data)


def external_references(text: str) -> list[str]:
    """References in an HTML page that would reach outside it (anything but data: and #)."""
    parser = _Refs()
    parser.feed(text)
    bad = [r for r in parser.refs if not r.strip().strip("'\"").startswith(("data:", "#"))]
    bad += [t for t in parser.tags if t in ("script", "link", "iframe", "object", "embed", "base")]
    return bad


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    scn = short_paper_scenario(2.0, [5, 10], "<report test>")
    out = tmp_path_factory.mktemp("report")
    res = run_sweep(scn, out, trials=2, workers=1, progress=False, figures=False)
    sweep_plots.plot_rmse_vs_count(res.scenario, res, out / "rmse_vs_count.png")
    path = html_report.write_sweep_report(out, json.loads((out / "metrics.json").read_text()))
    return path, res


def test_the_report_references_nothing_outside_itself(report):
    path, res = report
    text = path.read_text()
    assert external_references(text) == []
    assert text.count("data:image/png;base64,") == 1
    for mode in res.scenario.modes:
        assert mode in text
    assert "time-averaged (final epoch)" in text and "leonav_version" not in text and "leonav version" in text


def test_the_checker_finds_external_references():
    assert external_references('<img src="https://x/y.png"><p style="background:url(//x/z)">') == [
        "https://x/y.png", "//x/z"]
    assert external_references('<script src="data:,1"></script>') == ["script"]


def test_chromium_renders_the_tables_and_decodes_the_figures(report, tmp_path):
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    if browser is None:
        pytest.skip("needs Debian's chromium for a headless render (apt-get install chromium); not found on PATH")
    path, res = report
    probe = tmp_path / "probe.html"  # a copy with a probe script: image sizes as decoded by the browser
    probe.write_text(path.read_text().replace(
        "</body>", "<script>document.body.setAttribute('data-widths', Array.from(document.images)"
                   ".map(i => i.naturalWidth).join(','));</script></body>"))
    cmd = [browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
           "--host-resolver-rules=MAP * ~NOTFOUND", "--proxy-server=127.0.0.1:9", "--no-first-run",
           f"--user-data-dir={tmp_path / 'profile'}", "--virtual-time-budget=2000", "--dump-dom", probe.as_uri()]
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr[-2000:]
    dom = run.stdout
    widths = [int(w) for w in re.search(r'data-widths="([^"]*)"', dom).group(1).split(",") if w]
    assert widths and all(w >= 300 for w in widths), widths
    assert dom.count("<tr>") >= 1 + len(res.summaries) and "leo-alpha+imu" in dom
    shot = tmp_path / "shot.png"
    run = subprocess.run([*cmd[:-2], "--window-size=1000,1400", f"--screenshot={shot}", path.as_uri()],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0 and shot.stat().st_size > 10_000, run.stderr[-2000:]


def test_sweep_without_figures_draws_none_and_embeds_no_stale_one(tmp_path, capsys):
    """`leonav sweep --no-figures`: the numbers and report.html, no PNG drawn, and a PNG an earlier
    run left in the --out folder is not shown as this run's."""
    import tomli_w

    from leonav_runtime.cli import main
    from leonav_runtime.scenarios.load import load_scenario

    raw = load_scenario("paper").raw
    raw["time"]["duration_s"] = 2.0
    (tmp_path / "short.toml").write_text(tomli_w.dumps(raw))
    out = tmp_path / "out"
    out.mkdir()
    stale = b"\x89PNG\r\n\x1a\n stale"
    (out / "rmse_vs_count.png").write_bytes(stale)
    argv = ["sweep", str(tmp_path / "short.toml"), "--counts", "5", "--modes", "gps+imu", "--trials", "2",
            "--workers", "1", "--no-progress", "--no-figures", "--out", str(out)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "results:" in printed and ".png" not in printed.split("results:")[1]
    assert sorted(p.name for p in out.glob("*.png")) == ["rmse_vs_count.png"]
    assert (out / "rmse_vs_count.png").read_bytes() == stale
    text = (out / "report.html").read_text()
    assert "data:image/png" not in text and "gps+imu" in text
    assert json.loads((out / "metrics.json").read_text())["results"]
