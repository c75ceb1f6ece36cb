"""GNSS measurements and broadcast ephemerides: RINEX navigation/observation files, u-blox
RAWX/SFRBX logs, one ephemeris table and one observation table (docs/gnss.md)."""
