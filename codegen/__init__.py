"""Code generation: models -> casadi.Functions -> C in leonav_runtime/gen/.

Entry points: `generate(output_dir)` and `python -m codegen [--out DIR] [--check]`.
Importing this package generates nothing.
"""
from codegen.generate import diff_against, default_output_dir, generate

__all__ = ["generate", "diff_against", "default_output_dir"]
