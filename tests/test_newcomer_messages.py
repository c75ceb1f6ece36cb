"""Messages a newcomer meets: they name what exists and what to do."""
from __future__ import annotations

import pytest

from leonav_runtime.beacons import capture_io
from leonav_runtime.common.errors import UserInputError


def test_a_missing_capture_names_the_simulated_recording_beside_it(tmp_path):
    """`beacons sim.cu8 --simulate` writes sim.sigmf-data/-meta; rerunning on sim.cu8 points at them."""
    (tmp_path / "sim.sigmf-data").write_bytes(b"\0" * 16)
    (tmp_path / "sim.sigmf-meta").write_text("{}")
    with pytest.raises(UserInputError, match=r"sim\.cu8: capture data file not found; found sim\.sigmf-data, "
                                             r"sim\.sigmf-meta beside it"):
        capture_io.open_capture(tmp_path / "sim.cu8", "cu8")
    with pytest.raises(UserInputError, match=r"other\.cu8: capture data file not found$"):
        capture_io.open_capture(tmp_path / "other.cu8", "cu8")
