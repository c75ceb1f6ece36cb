"""Monte Carlo sweeps (`leonav sweep`): trials per mode and Starlink count (montecarlo.py) on an
executor (executors.py), the run and the paper's findings (run.py, paper_values.py), its
results folder (report.py, plots.py), and the snapshot CRB check (crb.py)."""
