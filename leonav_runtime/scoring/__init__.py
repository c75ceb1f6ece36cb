"""Scoring and trajectory export shared by `leonav run` (dataset descriptions) and `leonav replay`
(recorded sessions): error statistics (errors.py) and the geodetic trajectory files (export.py:
CSV, RTKLIB .pos, KML, GPX). Each command's own scoring (dataset outages and yaw, replay truth
with attitude) is built on these."""
