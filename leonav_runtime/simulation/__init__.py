"""Simulation: truth through the generated mechanization (simulate.py, trajectory.py), the
satellites a scenario sees (visibility.py), sensor errors (sensor_errors.py), truth != filter
switches (realism.py) and synthetic recorded sessions (session_synth.py)."""
