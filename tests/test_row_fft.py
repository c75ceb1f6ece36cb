"""The STFT's row FFT is scipy.fft.fft's, bit for bit, whichever way it is loaded (issue 25:
the beacon command's start-up without SciPy's array-API layer)."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import scipy.fft

from leonav_runtime.beacons import row_fft as rf


def _frames(rows: int, n: int, dtype, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return (rng.standard_normal((rows, n)) + 1j * rng.standard_normal((rows, n))).astype(dtype)


@pytest.mark.parametrize("rows, n, dtype, workers", [
    (64, 32768, np.complex64, 2), (3, 1000, np.complex64, 1), (5, 4096, np.complex128, 2), (1, 17, np.complex64, 1)])
def test_equals_scipy_fft_bit_for_bit_in_place(rows, n, dtype, workers):
    x = _frames(rows, n, dtype)
    want = scipy.fft.fft(x, axis=1, workers=workers)
    got = rf.row_fft(x, workers)
    assert got is x and got.dtype == dtype
    assert np.array_equal(got.view(np.uint8), want.view(np.uint8))


def test_refuses_what_it_cannot_transform_in_place():
    x = _frames(4, 64, np.complex64)
    with pytest.raises(ValueError, match="C-contiguous complex"):
        rf.row_fft(x[:, ::2])
    with pytest.raises(ValueError, match="float32"):
        rf.row_fft(x.real.copy())
    x.flags.writeable = False
    with pytest.raises(ValueError, match="writable False"):
        rf.row_fft(x)


def test_a_scipy_whose_extension_does_not_load_or_answers_otherwise_falls_back(monkeypatch):
    """A missing or differently called extension gives scipy.fft.fft, the same numbers."""
    class Wrong:  # a c2c with another argument order: its output fails the 4-point check
        @staticmethod
        def c2c(a, axes, forward, norm, out, workers):
            return np.conj(a)

    def fails():
        raise ImportError("no pocketfft here")

    x = _frames(2, 256, np.complex64)
    want = scipy.fft.fft(x, axis=1)
    for loader in (fails, lambda: None, lambda: Wrong):
        monkeypatch.setattr(rf, "_load_extension", loader)
        rf.row_fft_function.cache_clear()
        try:
            assert rf.row_fft_function() is rf._public_fft
            assert np.array_equal(rf.row_fft(x.copy()), want)
        finally:
            rf.row_fft_function.cache_clear()
    monkeypatch.undo()
    assert rf.row_fft_function() is not rf._public_fft   # this SciPy's own extension


_FRESH = """
import sys
import numpy as np
from leonav_runtime.beacons import row_fft as rf
x = (np.arange(24.0) * 1j + np.cos(np.arange(24.0))).astype(np.complex64).reshape(2, 12)
got = rf.row_fft(x.copy())
before = sorted(m for m in sys.modules if m.startswith("scipy"))
ext = sys.modules[rf._NAME]
import scipy.fft
print(before == [rf._NAME], rf.row_fft_function() is not rf._public_fft,
      scipy.fft._pocketfft.basic.pfft is ext, np.array_equal(got, scipy.fft.fft(x, axis=1)))
"""


def test_a_fresh_interpreter_loads_only_the_extension_and_scipy_reuses_it():
    """Without scipy.fft imported first: the extension alone is loaded (no SciPy package), and
    a later `import scipy.fft` finds that same module object instead of initialising it again."""
    out = subprocess.run([sys.executable, "-c", _FRESH], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["True"] * 4
