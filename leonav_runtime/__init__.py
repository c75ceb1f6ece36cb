"""leonav runtime: orbits, geometry, the compiled generated filter, simulation, CLI.

The filter that runs here is the generated C in `leonav_runtime/gen/`, compiled and
loaded without importing casadi.
"""
__version__ = "0.1.0"
