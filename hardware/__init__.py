"""Device side of leonav (installed as `leonav.hardware`)."""
if __name__ != "leonav.hardware":  # the folder hardware/ is the package leonav.hardware (setup.py), never a top-level `hardware`
    raise ModuleNotFoundError(f"{__name__!r}: this folder installs as `leonav.hardware`; import it under that name")
