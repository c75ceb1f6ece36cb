"""`leonav tle fetch` against hostile servers (a local http.server on 127.0.0.1, no internet).

Truncated replies that still parse, bodies shorter than their Content-Length, oversized
and endless bodies, dripping servers, redirect loops, malformed URLs, bad timeouts and
unwritable caches: each is refused with one clear error, within the deadline, and the
cache is never damaged. Every server handler is bounded (a fixed number of writes, and
it stops when the client goes away).
"""
from __future__ import annotations

import http.server
import json
import time
from contextlib import contextmanager

import pytest

from leonav_runtime.cli import main as leonav_main
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.orbits import FetchError, RejectedElementsWarning, fetch_group, load_elements
from tests.conftest import local_http_server, shared_file

QUERY = "?GROUP=gps-ops&FORMAT=tle"


def _gps_body() -> bytes:
    return shared_file("tle/gps-ops_2026-03-09.txt").read_bytes()


def _send(handler, data: bytes) -> bool:
    try:
        handler.wfile.write(data)
        handler.wfile.flush()
        return True
    except (BrokenPipeError, ConnectionResetError):
        return False


@contextmanager
def hostile_server(behaviours: dict):
    """Threaded HTTP/1.0 server on 127.0.0.1; behaviours map a path (without query) to fn(handler)."""
    hits: list[str] = []

    class Handler(http.server.BaseHTTPRequestHandler):
        def do_GET(self):  # noqa: N802 (http.server API)
            hits.append(self.path)
            behaviour = behaviours.get(self.path.split("?")[0])
            if behaviour is None:
                self.send_response(404)
                self.send_header("Content-Length", "0")
                self.end_headers()
                return
            behaviour(self)

        def log_message(self, *args):
            pass

    with local_http_server(Handler) as base:
        yield base, hits


def ok(body: bytes):
    def behaviour(h):
        h.send_response(200)
        h.send_header("Content-Length", str(len(body)))
        h.end_headers()
        _send(h, body)
    return behaviour


def short_body(body: bytes):
    def behaviour(h):  # announces the whole body, sends half, closes
        h.send_response(200)
        h.send_header("Content-Length", str(len(body)))
        h.end_headers()
        _send(h, body[: len(body) // 2])
    return behaviour


def endless(declared: int | None, limit_bytes: int = 3_000_000):
    def behaviour(h):  # a "600 MB" reply: sends at most limit_bytes, stops when the client leaves
        h.send_response(200)
        if declared is not None:
            h.send_header("Content-Length", str(declared))
        h.end_headers()
        block = b"0" * 65536
        for _ in range(limit_bytes // len(block)):
            if not _send(h, block):
                return
    return behaviour


def drip(body: bytes, interval_s: float = 0.1, max_writes: int = 120):
    def behaviour(h):  # a valid reply, one line per interval (bounded: max_writes lines)
        h.send_response(200)
        h.send_header("Content-Length", str(len(body)))
        h.end_headers()
        for line in body.splitlines(keepends=True)[:max_writes]:
            if not _send(h, line):
                return
            time.sleep(interval_s)
    return behaviour


def drip_headers(interval_s: float = 0.1, max_lines: int = 90):
    def behaviour(h):  # the status line, then one header line per interval, never the body
        if not _send(h, b"HTTP/1.0 200 OK\r\n"):
            return
        for k in range(max_lines):
            if not _send(h, f"X-Slow-{k}: 1\r\n".encode()):
                return
            time.sleep(interval_s)
    return behaviour


def redirect_to(path: str):
    def behaviour(h):
        h.send_response(302)
        h.send_header("Location", path)
        h.send_header("Content-Length", "0")
        h.end_headers()
    return behaviour


def test_truncated_reply_that_parses_does_not_replace_a_good_cache(tmp_path, capsys):
    body = _gps_body()
    lines = body.decode().splitlines(keepends=True)
    truncated = "".join(lines[:18]).encode()  # 6 of 32 satellites, cut at an entry boundary: parses cleanly
    cache = tmp_path / "cache"
    with hostile_server({"/good": ok(body), "/cut": ok(truncated)}) as (base, _):
        fetch_group("gps-ops", fmt="tle", cache_dir=cache, url_base=f"{base}/good", timeout_s=5)
        with pytest.raises(FetchError, match=r"only 6 element sets where the cached gps\.tle has 32.*--force"):
            fetch_group("gps-ops", fmt="tle", cache_dir=cache, url_base=f"{base}/cut", timeout_s=5)
        assert (cache / "gps.tle").read_bytes() == body and len(load_elements(cache / "gps.tle")) == 32
        assert json.loads((cache / "gps.tle.meta.json").read_text())["count"] == 32
        rc = leonav_main(["tle", "fetch", "gps-ops", "--format", "tle", "--cache", str(cache), "--url-base", f"{base}/cut"])
        assert rc == 2 and "reply refused" in capsys.readouterr().err
        # --force accepts it, and says so
        rc = leonav_main(["tle", "fetch", "gps-ops", "--format", "tle", "--cache", str(cache), "--url-base", f"{base}/cut", "--force"])
        assert rc == 0 and "accepted with --force" in capsys.readouterr().out
    meta = json.loads((cache / "gps.tle.meta.json").read_text())
    assert meta["count"] == 6 and meta["previous_count"] == 32 and meta["forced"] is True
    assert not list(cache.glob("*.part")) and not list(cache.glob(".*.part"))


def test_reply_with_a_rejected_entry_is_refused_unless_forced(tmp_path):
    lines = _gps_body().decode().splitlines(keepends=True)
    damaged = "".join(lines[:-1]) + lines[-1][:30] + "\n"  # the last line cut mid-way
    with hostile_server({"/x": ok(damaged.encode())}) as (base, _):
        with pytest.raises(FetchError, match=r"1 rejected entries \(first: line 96: truncated line 2"):
            fetch_group("gps-ops", fmt="tle", cache_dir=tmp_path, url_base=f"{base}/x", timeout_s=5)
        assert not (tmp_path / "gps.tle").exists()
        path = fetch_group("gps-ops", fmt="tle", cache_dir=tmp_path, url_base=f"{base}/x", timeout_s=5, force=True)
    with pytest.warns(RejectedElementsWarning):
        assert len(load_elements(path)) == 31


def test_body_shorter_than_content_length_is_a_clear_error(tmp_path):
    with hostile_server({"/short": short_body(_gps_body())}) as (base, _):
        with pytest.raises(FetchError, match=r"reply ended after \d+ of the \d+ bytes"):
            fetch_group("gps-ops", fmt="tle", cache_dir=tmp_path, url_base=f"{base}/short", timeout_s=5)
    assert not (tmp_path / "gps.tle").exists()


@pytest.mark.parametrize("declared", [600_000_000, None])
def test_oversized_reply_is_refused_without_reading_it_all(tmp_path, declared):
    with hostile_server({"/big": endless(declared)}) as (base, _):
        t0 = time.monotonic()
        with pytest.raises(FetchError, match=r"larger than the limit of 1 MB \(raise it with --max-mb\)"):
            fetch_group("gps-ops", fmt="tle", cache_dir=tmp_path, url_base=f"{base}/big", timeout_s=10, max_bytes=1_000_000)
        assert time.monotonic() - t0 < 5


def test_cli_default_size_limit_refuses_a_600_mb_reply(tmp_path, capsys):
    with hostile_server({"/big": endless(600_000_000, limit_bytes=65536)}) as (base, _):
        rc = leonav_main(["tle", "fetch", "gps-ops", "--format", "tle", "--cache", str(tmp_path), "--url-base", f"{base}/big"])
    err = capsys.readouterr().err
    assert rc == 2 and "reply of 600.0 MB is larger than the limit of 64 MB" in err


def test_dripping_server_cannot_hold_the_download_past_the_timeout(tmp_path):
    # one line every 0.1 s: each read is quick, so a per-read timeout never fired (took ~10 s)
    with hostile_server({"/drip": drip(_gps_body())}) as (base, _):
        t0 = time.monotonic()
        with pytest.raises(FetchError, match=r"did not finish within --timeout 1 s"):
            fetch_group("gps-ops", fmt="tle", cache_dir=tmp_path, url_base=f"{base}/drip", timeout_s=1.0)
        assert time.monotonic() - t0 < 2.5
    assert not (tmp_path / "gps.tle").exists()


def test_server_dripping_headers_cannot_hold_the_download_either(tmp_path):
    with hostile_server({"/slow": drip_headers()}) as (base, _):
        t0 = time.monotonic()
        with pytest.raises(FetchError, match=r"did not finish within --timeout 1 s"):
            fetch_group("gps-ops", fmt="tle", cache_dir=tmp_path, url_base=f"{base}/slow", timeout_s=1.0)
        assert time.monotonic() - t0 < 2.5


def test_redirect_loop_is_bounded(tmp_path):
    with hostile_server({"/loop": redirect_to("/loop"), "/moved": redirect_to("/good"),
                         "/good": ok(_gps_body())}) as (base, hits):
        with pytest.raises(FetchError, match="more than 5 redirects"):
            fetch_group("gps-ops", fmt="tle", cache_dir=tmp_path, url_base=f"{base}/loop", timeout_s=5)
        assert len(hits) == 6
        path = fetch_group("gps-ops", fmt="tle", cache_dir=tmp_path, url_base=f"{base}/moved", timeout_s=5)
    assert len(load_elements(path)) == 32


@pytest.mark.parametrize("url", ["http://[::1", "ftp://example.org/gp.php", "file:///etc/passwd",
                                 "http://127.0.0.1:99999/gp.php", "not a url", "http:///gp.php",
                                 "http://127.0.0.1:8/gp php"])
def test_malformed_url_base_is_one_clear_error(tmp_path, url, capsys):
    with pytest.raises(UserInputError, match=r"--url-base"):
        fetch_group("gps-ops", fmt="tle", cache_dir=tmp_path, url_base=url, timeout_s=1)
    assert leonav_main(["tle", "fetch", "gps-ops", "--format", "tle", "--cache", str(tmp_path), "--url-base", url]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("leonav tle fetch: error: --url-base")


@pytest.mark.parametrize("timeout", ["-1", "nan", "inf", "0", "1e9"])
def test_bad_timeout_is_one_clear_error(tmp_path, timeout, capsys):
    assert leonav_main(["tle", "fetch", "gps-ops", "--format", "tle", "--cache", str(tmp_path), "--timeout", timeout,
                        "--url-base", "http://127.0.0.1:9/gp.php"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--timeout" in err[0] and "expected a number of seconds" in err[0]


def test_bad_max_mb_is_one_clear_error(tmp_path, capsys):
    assert leonav_main(["tle", "fetch", "gps-ops", "--format", "tle", "--cache", str(tmp_path), "--max-mb", "nan"]) == 2
    assert "--max-mb" in capsys.readouterr().err


def test_unwritable_cache_is_an_io_error_and_nothing_is_lost(tmp_path, capsys):
    not_a_folder = tmp_path / "cache"
    not_a_folder.write_text("I am a file")
    with hostile_server({"/good": ok(_gps_body())}) as (base, _):
        with pytest.raises(OSError, match="cannot write the TLE cache"):
            fetch_group("gps-ops", fmt="tle", cache_dir=not_a_folder, url_base=f"{base}/good", timeout_s=5)
        rc = leonav_main(["tle", "fetch", "gps-ops", "--format", "tle", "--cache", str(not_a_folder / "sub"),
                          "--url-base", f"{base}/good"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 3 and len(err) == 1
    assert err[0].startswith("leonav tle fetch: error: ") and "choose another folder with --cache" in err[0]
    assert not_a_folder.read_text() == "I am a file"
