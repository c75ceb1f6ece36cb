"""Plain-text tables for the console: every column as wide as its widest cell.

Fixed widths break as soon as a value is longer than planned (a long motion name, a weak-direction
count, a study axis such as duration_s=120.0); measuring the cells keeps the columns straight.
"""
from __future__ import annotations

from typing import Sequence

GAP = "  "  # between columns


def text_table(header: Sequence[str], rows: Sequence[Sequence[object]], align: str) -> list[str]:
    """Lines of a table: `align` has one letter per column, 'l' (left) or 'r' (right); the last
    column is not padded (free text such as direction lists may follow)."""
    if len(align) != len(header) or any(a not in "lr" for a in align):
        raise ValueError(f"align {align!r}: expected one of l/r per column ({len(header)} columns)")
    cells = [[str(c) for c in header]] + [[str(c) for c in row] for row in rows]
    if any(len(row) != len(header) for row in cells):
        raise ValueError("every row needs one cell per header column")
    widths = [max(len(row[j]) for row in cells) for j in range(len(header))]
    lines = []
    for row in cells:
        parts = []
        for j, (cell, a) in enumerate(zip(row, align)):
            if j == len(row) - 1 and a == "l":
                parts.append(cell)
            else:
                parts.append(cell.ljust(widths[j]) if a == "l" else cell.rjust(widths[j]))
        lines.append(GAP.join(parts).rstrip())
    return lines
