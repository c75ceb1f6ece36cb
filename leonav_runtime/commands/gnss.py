"""`leonav gnss`: RINEX/u-blox GNSS tools (see leonav_runtime/gnss/cli.py)."""
from leonav_runtime.gnss.cli import register  # noqa: F401
