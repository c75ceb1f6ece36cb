"""Sensitivity studies: one- and two-parameter grids over scenario fields (`leonav study`).

`spec.load_study` reads and validates a study file into cells (complete scenarios);
`run.run_study` runs them on the sweep's executors and writes CSV, JSON and a figure.
"""
