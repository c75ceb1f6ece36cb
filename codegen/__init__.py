"""Code generation: models -> casadi.Functions -> C in leonav_runtime/gen/.

Entry points: `codegen.generate.generate(output_dir)`, `codegen.generate.diff_against(dir)`
and `python -m leonav.codegen [--out DIR] [--check]`. Importing this package generates nothing
and loads no casadi, so `leonav --help` (which registers `leonav codegen`) works without it.
"""
if __name__ != "leonav.codegen":  # the folder codegen/ is the package leonav.codegen (setup.py), never a top-level `codegen`
    raise ModuleNotFoundError(f"{__name__!r}: this folder installs as `leonav.codegen`; import it under that name")

