"""Code generation: models -> casadi.Functions -> C in leonav_runtime/gen/.

Entry points: `codegen.generate.generate(output_dir)`, `codegen.generate.diff_against(dir)`
and `python -m codegen [--out DIR] [--check]`. Importing this package generates nothing
and loads no casadi, so `leonav --help` (which registers `leonav codegen`) works without it.
"""
