"""Console tables keep their columns straight whatever the cell widths."""
from __future__ import annotations

import pytest

from leonav_runtime.common.text_table import text_table


def test_columns_are_as_wide_as_their_widest_cell_and_aligned_as_asked():
    lines = text_table(["mode", "rank", "note"], [["gps+imu", "14/22", "a"], ["leo-doppler+alpha+imu", "9/22", "bb"]],
                       "lrl")
    w = len("leo-doppler+alpha+imu")
    assert lines == ["mode".ljust(w) + "   rank  note",
                     "gps+imu".ljust(w) + "  14/22  a",
                     "leo-doppler+alpha+imu   9/22  bb"]


def test_bad_shapes_are_refused():
    with pytest.raises(ValueError, match="align"):
        text_table(["a", "b"], [["1", "2"]], "l")
    with pytest.raises(ValueError, match="one cell per header"):
        text_table(["a", "b"], [["1"]], "ll")
