"""Sensitivity studies: one- and two-parameter grids over scenario fields (`leonav study`).

`spec.load_study` reads and validates a study file into cells (complete scenarios);
`run.run_study` runs them on the sweep's executors and writes CSV, JSON and a figure.
"""

from pathlib import Path

# the shipped study files (`leonav study NAME`); here, not in spec.py, so the command line can
# list them in its help without importing the scenario machinery
BUILTIN_STUDY_DIR = Path(__file__).with_name("studies")


def shipped_studies() -> list[str]:
    """Names of the shipped studies, sorted."""
    return sorted(p.stem for p in BUILTIN_STUDY_DIR.glob("*.toml"))
