"""Scenarios: the TOML files a simulation is described by (the built-in ones sit in this
folder), their schema (schema.py), loading and validation to SI (load.py), command-line and
API overrides (overrides.py), and the memory check of a run (run_size.py)."""
