"""The corrections line protocol and the rover's store: round trip, bad input counted, age rules."""
from __future__ import annotations

import math

import numpy as np
import pytest

from leonav_runtime.base import protocol
from leonav_runtime.base.client import feed_lines
from leonav_runtime.inputs import DopplerRateTable, DopplerTable
from leonav_runtime.inputs.corrections import DifferentialCorrections

T0 = 1_771_848_000.0


def _cor(sat=44713, t=T0 + 5.0, value=-2.5, sigma=0.4, obs="doppler_rate", const="starlink"):
    return protocol.Correction(const, sat, obs, t, value, sigma)


def test_lines_round_trip():
    c = _cor()
    back = protocol.parse_line(protocol.correction_line(c).encode())
    assert back == c
    h = protocol.parse_line(protocol.header_line(43.1, -77.5, 170.0))
    assert (h.lat_deg, h.lon_deg, h.h_m, h.time_scale) == (43.1, -77.5, 170.0, "UTC")
    assert protocol.parse_line(protocol.heartbeat_line(T0)).t_utc_s == T0


def test_garbled_lines_are_counted_with_one_reason_each():
    good = protocol.correction_line(_cor())
    flipped = good.replace("-2.50000", "-2.60000")               # a digit changed in transit: checksum catches it
    body = good.split("*")[0]
    bad = [flipped, body + "\n", "LNVC 2 HB 1.0*" + protocol.checksum("LNVC 2 HB 1.0") + "\n",
           protocol._seal("LNVC 1 COR starlink 44713 doppler_rate 1.0 nan Hz/s 0.4"),
           protocol._seal("LNVC 1 COR starlink 44713 doppler_rate 1.0 -2.5 Hz 0.4"),
           protocol._seal("LNVC 1 COR starlink 44713 doppler_rate 1.0 -2.5 Hz/s -0.4"),
           protocol._seal("LNVC 1 COR starlink x doppler_rate 1.0 -2.5 Hz/s 0.4"),
           "\xff\xfe junk", "x" * 300]
    for line in bad:
        with pytest.raises(protocol.LineError):
            protocol.parse_line(line.encode("latin-1"))
    store = DifferentialCorrections()
    counts: dict = {}
    feed_lines(store, [b.encode("latin-1") for b in bad] + [good.encode()], counts)
    assert store.counts["rejected_garbled"] == len(bad) == 9
    assert store.counts["received"] == 1 and counts["lines"] == 10
    assert "checksum" in store.first_rejection["garbled"]


def test_other_constellation_and_late_corrections_are_refused_and_counted():
    store = DifferentialCorrections(max_age_s=5.0, epoch_unix=T0)
    assert not store.add("oneweb", 1, "doppler_rate", T0, 1.0, 0.1)
    assert not store.add("starlink", 1, "pseudorange", T0, 1.0, 0.1)
    assert store.counts["rejected_other_constellation"] == 1 and store.counts["rejected_observable"] == 1
    tab = DopplerRateTable(np.array([20.0]), np.array([1]), np.array([-10.0]), 1.0, np.zeros((1, 9)))
    store.apply(tab)                                        # the rover is now at T0 + 20 s
    assert not store.add("starlink", 1, "doppler_rate", T0 + 10.0, 1.0, 0.1)   # 10 s behind: late
    assert store.counts["rejected_late"] == 1


def test_apply_subtracts_the_latest_fresh_correction_and_falls_back_when_stale():
    store = DifferentialCorrections(max_age_s=3.0, epoch_unix=T0)
    for t, v in ((0.0, 1.0), (1.0, 2.0), (2.0, 3.0)):
        store.add("starlink", 7, "doppler_rate", T0 + t, v, 0.3)
    t = np.array([0.2, 1.4, 2.6, 4.9, 5.5, 1.0])
    sat = np.array([7, 7, 7, 7, 7, 8])
    tab = DopplerRateTable(t, sat, np.full(6, 10.0), 0.4, np.zeros((6, 9)))
    out = store.apply(tab)
    # 0.2 -> the 0 s one; 1.4 -> 1 s (0.5 s tolerance reaches 1.9, not 2); 2.6 -> 2 s; 4.9 -> 2 s, age 2.9;
    # 5.5 -> age 3.5 > 3: stale, uncorrected; satellite 8 has none
    np.testing.assert_allclose(out.z, [9.0, 8.0, 7.0, 7.0, 10.0, 10.0])
    np.testing.assert_allclose(out.sigma[:4], math.hypot(0.4, 0.3))
    np.testing.assert_allclose(out.sigma[4:], 0.4)
    assert store.counts["doppler_rate_applied"] == 4 and store.counts["doppler_rate_stale"] == 1
    assert store.counts["doppler_rate_none"] == 1
    assert store.age_summary()["max_s"] == pytest.approx(2.9)
    assert store.state == "applied"
    later = DopplerRateTable(np.array([9.0]), np.array([7]), np.array([10.0]), 0.4, np.zeros((1, 9)))
    assert store.apply(later).z[0] == 10.0 and store.state == "fallback"
    # another observable's table passes untouched
    dop = DopplerTable(np.array([1.0]), np.array([7]), np.array([5.0]), 1.0, np.zeros((1, 9)))
    assert store.apply(dop).z[0] == 5.0 and store.counts["doppler_none"] == 1


def test_doppler_corrections_lose_the_base_lo_offset():
    """The base's LO offset is common to its satellites: the across-satellite mean removes it."""
    from leonav_runtime.base import compute
    from leonav_runtime.core import navfuncs

    nav = navfuncs.NavFunctions()
    origin = (math.radians(43.08), math.radians(-77.68), 170.0)
    sat = np.zeros((4, 9))
    r0 = 6378137.0 + 550e3
    for k, (lat, lon) in enumerate([(43.5, -77.0), (44.0, -78.5), (42.2, -77.9), (43.0, -76.0)]):
        la, lo = math.radians(lat), math.radians(lon)
        sat[k, 0:3] = r0 * np.array([math.cos(la) * math.cos(lo), math.cos(la) * math.sin(lo), math.sin(la)])
        sat[k, 3:6] = 7500.0 * np.array([-math.sin(lo), math.cos(lo), 0.0])
    tab = DopplerTable(np.zeros(4), np.arange(4), np.zeros(4), 5.0, sat)
    h = compute.predicted(tab, origin, 11.325e9, nav)
    effect = np.array([30.0, -10.0, 5.0, -25.0])           # what the orbit error does to each satellite
    tab.z = h + effect + 1234.5                           # ... plus the base's LO offset
    c, _ = compute.raw_corrections(tab, origin, 11.325e9, nav)
    np.testing.assert_allclose(c, effect - effect.mean(), atol=1e-6)
