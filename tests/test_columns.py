"""common/columns.columnwise gives the plain ufunc's values bit for bit, broadcasting included."""
from __future__ import annotations

import numpy as np
import pytest

from leonav_runtime.common.columns import columnwise


@pytest.mark.parametrize("ufunc", [np.add, np.subtract, np.multiply, np.divide])
def test_columnwise_equals_the_ufunc(ufunc):
    rng = np.random.default_rng(11)
    a = rng.standard_normal((5, 40, 3)) * 10.0 ** rng.uniform(-8, 8, (5, 40, 3))
    cases = [rng.standard_normal((5, 40, 3)), rng.standard_normal(3), rng.standard_normal((5, 1, 3)),
             rng.standard_normal((40, 1)), rng.standard_normal((40, 6))[:, 3:]]   # the last: a strided view
    for b in cases:
        want = ufunc(a, b)
        out = np.full_like(a, np.nan)
        assert columnwise(ufunc, a, b, out) is out
        assert out.tobytes() == want.tobytes()
    view = np.full((5, 40, 6), np.nan)          # writing into half of a wider last axis
    columnwise(ufunc, a, cases[0], view[:, :, 3:])
    assert view[:, :, 3:].tobytes() == ufunc(a, cases[0]).tobytes() and np.isnan(view[:, :, :3]).all()
    inplace = a.copy()
    columnwise(ufunc, inplace, cases[1], inplace)
    assert inplace.tobytes() == ufunc(a, cases[1]).tobytes()


def test_an_operand_overlapping_the_output_gives_the_ufuncs_answer():
    """out shifted by one column against its input: column by column would read written values."""
    rng = np.random.default_rng(12)
    arr = rng.standard_normal((4, 5, 4))
    want = arr.copy()
    np.add(want[..., 0:3], 1.5, out=want[..., 1:4])
    columnwise(np.add, arr[..., 0:3], 1.5, arr[..., 1:4])
    assert arr.tobytes() == want.tobytes()
