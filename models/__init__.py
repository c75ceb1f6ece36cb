"""Symbolic CasADi models of leonav (installed as `leonav.models`)."""
if __name__ != "leonav.models":  # the folder models/ is the package leonav.models (setup.py), never a top-level `models`
    raise ModuleNotFoundError(f"{__name__!r}: this folder installs as `leonav.models`; import it under that name")
