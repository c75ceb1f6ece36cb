"""CelesTrak fetch against a local HTTP server (no internet), and the `leonav tle` CLI."""
from __future__ import annotations

import http.server
import json
import socket
from contextlib import contextmanager
from pathlib import Path

import pytest

from leonav_runtime.cli import main as leonav_main
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.orbits import FetchError, fetch_group, load_elements
from tests.conftest import local_http_server, shared_file


@contextmanager
def serve(routes: dict[str, tuple[int, bytes]]):
    """HTTP server on 127.0.0.1 in a thread; routes map '/path?query' to (status, body)."""
    requests: list[str] = []

    class Handler(http.server.BaseHTTPRequestHandler):
        def do_GET(self):  # noqa: N802 (http.server API)
            requests.append(self.path)
            status, body = routes.get(self.path, (404, b"not found"))
            self.send_response(status)
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args):  # keep pytest output clean
            pass

    with local_http_server(Handler) as base:
        yield f"{base}/gp.php", requests


def _closed_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]  # closed again when the block ends


def test_fetch_writes_cache_and_sidecar(tmp_path):
    body = shared_file("tle/gps-ops_2026-03-09.txt").read_bytes()
    with serve({"/gp.php?GROUP=gps-ops&FORMAT=tle": (200, body)}) as (url, requests):
        path = fetch_group("gps-ops", fmt="tle", cache_dir=tmp_path / "cache", url_base=url, timeout_s=5)
    assert requests == ["/gp.php?GROUP=gps-ops&FORMAT=tle"]
    assert path == tmp_path / "cache" / "gps.tle" and path.read_bytes() == body
    meta = json.loads(path.with_name(path.name + ".meta.json").read_text())
    assert meta["count"] == 32 and meta["url"] == f"{url}?GROUP=gps-ops&FORMAT=tle"
    assert meta["downloaded_utc"].endswith("+00:00") and meta["epoch_min_utc"].startswith("2026-03-03")
    assert len(load_elements(path)) == 32


def test_default_cache_follows_xdg(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    body = shared_file("tle/gps-ops_2026-03-09.txt").read_bytes()
    with serve({"/gp.php?GROUP=gps-ops&FORMAT=tle": (200, body)}) as (url, _):
        path = fetch_group("gps-ops", fmt="tle", url_base=url, timeout_s=5)
    assert path == tmp_path / "xdg" / "leonav" / "tle" / "gps.tle"


def test_fetch_errors_are_clear_and_leave_no_file(tmp_path):
    cache = tmp_path / "cache"
    with serve({"/gp.php?GROUP=starlink&FORMAT=tle": (200, b"<html><body>Too many requests</body></html>")}) as (url, _):
        with pytest.raises(FetchError, match=r"reply is not element data \(first line '<html>"):
            fetch_group("starlink", fmt="tle", cache_dir=cache, url_base=url, timeout_s=5)
        with pytest.raises(FetchError, match=r"HTTP 404"):
            fetch_group("no-such-group", fmt="tle", cache_dir=cache, url_base=url, timeout_s=5)
    assert not (cache / "starlink.tle").exists()
    offline = f"http://127.0.0.1:{_closed_port()}/gp.php"
    with pytest.raises(FetchError, match=r"cannot download .*are you offline") as info:
        fetch_group("starlink", fmt="tle", cache_dir=cache, url_base=offline, timeout_s=2)
    assert isinstance(info.value, UserInputError) and offline in str(info.value)
    with pytest.raises(UserInputError, match="expected a CelesTrak group name"):
        fetch_group("../etc", fmt="tle", cache_dir=cache)


def test_cli_fetch_and_info(tmp_path, capsys):
    body = shared_file("tle/starlink_2026-02-23.txt").read_bytes()
    with serve({"/gp.php?GROUP=starlink&FORMAT=tle": (200, body)}) as (url, _):
        rc = leonav_main(["tle", "fetch", "starlink", "--format", "tle", "--cache", str(tmp_path / "c"), "--url-base", url])
    assert rc == 0 and "9543 element sets of group 'starlink'" in capsys.readouterr().out
    bad = tmp_path / "mixed.txt"
    lines = shared_file("tle/gps-ops_2026-03-09.txt").read_text().splitlines()
    lines[4] = lines[4][:40]  # truncate line 1 of the second entry
    bad.write_text("\n".join(lines) + "\n")
    rc = leonav_main(["tle", "info", str(bad), "--epoch", "2026-03-09T12:00:00Z", "--out", str(tmp_path / "o")])
    assert rc == 0
    info = json.loads((tmp_path / "o" / "tle_info.json").read_text())
    assert info["count"] == 31 and info["constellation"] == "gps" and info["rejected_count"] == 1
    assert info["rejected"][0]["line"] == 5 and "truncated line 1" in info["rejected"][0]["reason"]
    assert info["epoch_max_utc"].startswith("2026-03-09") and info["stale_count"] == 2
    offline = f"http://127.0.0.1:{_closed_port()}/gp.php"
    assert leonav_main(["tle", "fetch", "gps-ops", "--format", "tle", "--cache", str(tmp_path / "c"), "--url-base", offline,
                        "--timeout", "2"]) == 2
    assert "are you offline" in capsys.readouterr().err
    empty = tmp_path / "empty.tle"
    empty.write_text("")
    assert leonav_main(["tle", "info", str(empty), "--out", str(tmp_path / "o2")]) == 2
    assert "empty.tle: empty element file" in capsys.readouterr().err


def test_cli_builtin_writes_parseable_text(tmp_path):
    rc = leonav_main(["tle", "builtin", "gps", "--epoch", "2026-03-01T00:00:00Z", "--out", str(tmp_path)])
    assert rc == 0
    elements = load_elements(Path(tmp_path) / "gps_walker.tle")
    assert len(elements) == 31 and elements.constellation == "gps"


def _omm_bodies() -> tuple[bytes, bytes, list]:
    """OMM JSON and XML of the GPS TLE file, made by sgp4's own OMM exporter (outside reference)."""
    from xml.sax.saxutils import escape

    from sgp4 import exporter
    from sgp4.api import Satrec

    lines = [ln.rstrip() for ln in shared_file("tle/gps-ops_2026-03-09.txt").read_text().splitlines() if ln.strip()]
    records = [exporter.export_omm(Satrec.twoline2rv(lines[i + 1], lines[i + 2]), lines[i].strip())
               for i in range(0, len(lines), 3)]
    segments = "".join(
        "<segment><metadata>" + "".join(f"<{k}>{escape(str(v))}</{k}>" for k, v in r.items()
                                        if k in ("OBJECT_NAME", "OBJECT_ID", "CENTER_NAME", "REF_FRAME", "TIME_SYSTEM",
                                                 "MEAN_ELEMENT_THEORY"))
        + "</metadata><data><meanElements>" + "".join(f"<{k}>{v}</{k}>" for k, v in r.items() if k in (
            "EPOCH", "MEAN_MOTION", "ECCENTRICITY", "INCLINATION", "RA_OF_ASC_NODE", "ARG_OF_PERICENTER",
            "MEAN_ANOMALY")) + "</meanElements><tleParameters>" + "".join(
            f"<{k}>{v}</{k}>" for k, v in r.items() if k in ("EPHEMERIS_TYPE", "CLASSIFICATION_TYPE", "NORAD_CAT_ID",
                                                          "ELEMENT_SET_NO", "REV_AT_EPOCH", "BSTAR", "MEAN_MOTION_DOT",
                                                          "MEAN_MOTION_DDOT"))
        + "</tleParameters></data></segment>" for r in records)
    xml = f'<?xml version="1.0" encoding="UTF-8"?><ndm><omm id="CCSDS_OMM_VERS" version="2.0"><body>{segments}</body></omm></ndm>'
    return json.dumps(records).encode(), xml.encode(), records


@pytest.mark.parametrize("fmt,suffix", [("json", ".omm.json"), ("xml", ".omm.xml")])
def test_fetch_omm_formats_cache_the_same_satellites_as_the_tle(tmp_path, fmt, suffix):
    body_json, body_xml, records = _omm_bodies()
    tle = shared_file("tle/gps-ops_2026-03-09.txt").read_bytes()
    body = body_json if fmt == "json" else body_xml
    routes = {f"/gp.php?GROUP=gps-ops&FORMAT={fmt}": (200, body), "/gp.php?GROUP=gps-ops&FORMAT=tle": (200, tle)}
    with serve(routes) as (url, requests):
        path = fetch_group("gps", cache_dir=tmp_path, url_base=url, timeout_s=5, fmt=fmt)
        ref = fetch_group("gps-ops", cache_dir=tmp_path, url_base=url, timeout_s=5, fmt="tle")  # the alias
    assert requests == [f"/gp.php?GROUP=gps-ops&FORMAT={fmt}", "/gp.php?GROUP=gps-ops&FORMAT=tle"]
    assert path == tmp_path / f"gps{suffix}" and ref == tmp_path / "gps.tle"
    got, want = load_elements(path), load_elements(ref)
    assert list(got.norad_ids) == list(want.norad_ids) == [r["NORAD_CAT_ID"] for r in records]
    assert max(abs((a - b).total_seconds()) for a, b in zip(got.epochs_utc, want.epochs_utc)) < 1e-3
    meta = json.loads((tmp_path / f"gps{suffix}.meta.json").read_text())
    assert meta["format"] == fmt and meta["group"] == "gps" and meta["count"] == len(records)


def test_fetch_refuses_a_reply_in_another_format_and_keeps_the_cache(tmp_path):
    body_json, _, _ = _omm_bodies()
    tle = shared_file("tle/gps-ops_2026-03-09.txt").read_bytes()
    with serve({"/gp.php?GROUP=starlink&FORMAT=json": (200, tle)}) as (url, _):
        with pytest.raises(FetchError, match="reply is TLE data where JSON was asked"):
            fetch_group("starlink", cache_dir=tmp_path, url_base=url, timeout_s=5)
    assert not list(tmp_path.iterdir())


def test_fetch_cli_defaults_to_omm_json(tmp_path, capsys):
    body_json, _, records = _omm_bodies()
    with serve({"/gp.php?GROUP=gps-ops&FORMAT=json": (200, body_json)}) as (url, requests):
        rc = leonav_main(["tle", "fetch", "gps", "--cache", str(tmp_path), "--url-base", url])
    assert rc == 0 and requests == ["/gp.php?GROUP=gps-ops&FORMAT=json"]
    assert f"{len(records)} element sets of group 'gps' (JSON)" in capsys.readouterr().out


def test_verbose_flag_shows_the_download_steps(tmp_path, capsys):
    body_json, _, _ = _omm_bodies()
    with serve({"/gp.php?GROUP=gps-ops&FORMAT=json": (200, body_json)}) as (url, _):
        assert leonav_main(["tle", "fetch", "gps", "--cache", str(tmp_path), "--url-base", url]) == 0
        assert "info:" not in capsys.readouterr().err
        assert leonav_main(["-v", "tle", "fetch", "gps", "--cache", str(tmp_path), "--url-base", url]) == 0
    err = capsys.readouterr().err
    assert f"leonav tle fetch: info: GET {url}?GROUP=gps-ops&FORMAT=json" in err
    assert f"info: received {len(body_json)} bytes" in err
