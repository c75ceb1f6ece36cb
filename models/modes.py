"""Fusion modes: which observables feed the filter, named by their observables' mode words.

A mode name is `+`-joined words: satellite and GNSS words first (`gps`, `fix`, `pseudorange`;
LEO words after the prefix `leo-`: `leo-alpha`, `leo-doppler+alpha`), then `imu` (always: the
IMU propagates), then local sensors and motion constraints (`baro`, `mag`, `nhc`, `zupt`):
`gps+leo-alpha+imu`, `fix+imu+nhc+zupt`, `gps+imu+baro`. Each observable declares its word
(`registry.Observable.token`); the runtime reads a name with `leonav_runtime.core.modes`.

`PAPER_MODES` are the paper's six: the default mode list of every scenario (a sensor added
later is in none of them; its modes are asked for by name).
"""
from __future__ import annotations

PAPER_MODES = ("gps+imu", "leo-alpha+imu", "gps+leo-alpha+imu", "leo-ofdm+imu", "leo-alpha+ofdm+imu",
               "leo-doppler+alpha+imu")
