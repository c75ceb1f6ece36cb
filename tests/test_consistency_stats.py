"""The sweep's NEES and NIS sums (sweep/consistency.py) against LAPACK's solve and masked sums,
and the same values for a trial whether it is computed in a batch or alone."""
from __future__ import annotations

import numpy as np

from leonav_runtime.sweep import consistency


def _spd(rng, batch, n):
    A = rng.standard_normal((batch, n, n))
    scale = np.logspace(-3, 4, n)          # position m^2 .. attitude rad^2-like spread
    return (A @ np.swapaxes(A, 1, 2) + 0.1 * np.eye(n)) * scale[:, None] * scale[None, :]


def test_nees_equals_the_solve_and_does_not_depend_on_the_batch():
    rng = np.random.default_rng(3)
    P = _spd(rng, 300, 9).reshape(20, 15, 9, 9)
    err = rng.standard_normal((20, 15, 9)) * np.logspace(-3, 4, 9)
    got = consistency.nees(err, P)
    ref = np.einsum("bni,bni->bn", err, np.linalg.solve(P, err[..., None])[..., 0])
    assert got.shape == (20, 15)
    np.testing.assert_allclose(got, ref, rtol=1e-9)
    assert consistency.nees(err[7], P[7]).tobytes() == got[7].tobytes()


def test_nees_of_a_matrix_that_is_not_positive_definite_falls_back_to_the_solve():
    rng = np.random.default_rng(4)
    P = _spd(rng, 4, 3)
    P[2] = np.diag([1.0, -2.0, 3.0])        # indefinite: no Cholesky factor
    err = rng.standard_normal((4, 3))
    ref = np.einsum("ni,ni->n", err, np.linalg.solve(P, err[:, :, None])[:, :, 0])
    np.testing.assert_allclose(consistency.nees(err, P), ref, rtol=1e-12)


def test_nis_sums_count_applied_and_gated_updates_per_kind():
    kind = np.array([-1, 2, 5, 2, -1, 5, 5, 2])
    nis = np.array([9.0, 1.0, 2.0, 3.0, 9.0, 4.0, 5.0, 6.0])
    status = np.array([0, 0, 1, -1, 0, 0, 2, 1])      # -1 skipped, 2 failed: not counted
    sums, counts = consistency.nis_sums(*consistency.kind_index(kind), nis, status)
    assert sums == {2: 7.0, 5: 6.0} and counts == {2: 2, 5: 2}


def test_nis_sums_of_a_block_equal_each_trials_own():
    """The block's one bincount gives every trial exactly the sums and counts it gets alone."""
    rng = np.random.default_rng(5)
    kind = rng.choice([-1, -1, 3, 4, 9], size=500)
    kinds, index = consistency.kind_index(kind)
    nis = rng.exponential(1.0, size=(7, 500)) * 10.0 ** rng.uniform(-3, 3, size=(7, 500))
    status = rng.choice([-1, 0, 0, 1, 2], size=(7, 500)).astype(np.int32)
    block = consistency.nis_sums_many(kinds, index, nis, status)
    assert len(block) == 7
    for j in range(7):
        sums, counts = block[j]
        used = (index >= 0) & (status[j] >= 0) & (status[j] <= 1)
        alone = {int(k): 0.0 for k in kinds}
        for i in np.flatnonzero(used):          # record order, as a trial's own sum
            alone[int(kinds[index[i]])] += nis[j, i]
        assert sums == alone and counts == {int(k): int(np.sum(used & (index == i))) for i, k in enumerate(kinds)}
        assert consistency.nis_sums(kinds, index, nis[j], status[j]) == block[j]
