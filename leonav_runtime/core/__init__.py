"""The filter core: the generated C compiled and loaded (compiled.py, build_cache.py), its
Python face (filter.py: EKF, PCRB; navfuncs.py: single generated-function calls), the record
layout (records.py) and the parameter vector p (params.py). No casadi, no models/."""
