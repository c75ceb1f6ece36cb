"""The `leonav gnss` adapter (registered here on a bare parser: the command module is a hook
outside this package) and the SFRBX decoder entry for hardware.gnss.ubx.DECODERS."""
from __future__ import annotations

import argparse

import pytest

from leonav_runtime.gnss import sfrbx
from leonav.hardware.records import UbxFrame
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gnss.cli import register
from tests.conftest import shared_file


def _run(argv):
    parser = argparse.ArgumentParser()
    register(parser.add_subparsers())
    args = parser.parse_args(argv)
    return args.func(args)


def test_nav_obs_ubx_and_tle(capsys):
    nav = str(shared_file("gnss_rinex/07590920.05n"))
    assert _run(["gnss", "nav", nav]) == 0
    assert "162 ephemerides" in capsys.readouterr().out
    assert _run(["gnss", "obs", str(shared_file("gnss_rinex/07590920.05o")), "--nav", nav]) == 0
    assert '"with_state": 1872' in capsys.readouterr().out
    assert _run(["gnss", "ubx", str(shared_file("ubx/gpsd/ublox-neo-m8t.log"))]) == 0
    assert '"rows": 507' in capsys.readouterr().out
    d = "tle/rtklib_gnss_20121031/"
    assert _run(["gnss", "tle-vs-brdc", str(shared_file(d + "TLE_GNSS_20121101.txt")),
                 str(shared_file(d + "brdc3050.12n")), "--step", "3600"]) == 0
    assert " all " in capsys.readouterr().out


def test_bad_file_is_a_user_input_error(tmp_path):
    bad = tmp_path / "x.05n"
    bad.write_text("     9.99           N: GPS NAV DATA                         RINEX VERSION / TYPE\n")
    with pytest.raises(UserInputError, match=r"x\.05n:1: field RINEX VERSION"):
        _run(["gnss", "nav", str(bad)])


def test_decode_rxm_sfrbx_entry():
    payload = sfrbx.sfrbx_payload(7, list(range(10)))
    f = sfrbx.decode_rxm_sfrbx(UbxFrame(0.0, 0x02, 0x13, payload))
    assert (f.gnss_id, f.sv_id, f.version, f.words) == (0, 7, 2, list(range(10)))
    with pytest.raises(ValueError, match="8 \\+ 4\\*10"):
        sfrbx.decode_rxm_sfrbx(UbxFrame(0.0, 0x02, 0x13, payload[:-1]))
