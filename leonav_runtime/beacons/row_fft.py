"""The STFT's complex FFT along rows: SciPy's pocketfft, without `scipy.fft`'s package import.

Why not a plain `import scipy.fft`: that package's import also loads SciPy's array-API layer,
which clones NumPy's whole namespace (and with it `numpy.f2py`, `numpy.testing`, `numpy.ma`),
and `scipy.special` for its FFTLog. On the 2-vCPU build machine that is 0.3-0.45 s of CPU,
most of `leonav beacons`' fixed cost (docs/performance.md). The transform itself is SciPy's
compiled pocketfft extension (`scipy.fft._pocketfft.pypocketfft`), which imports nothing of
SciPy: it is loaded here from its file and registered in `sys.modules` under its own name, so
a later `import scipy.fft` (by the caller, a test, a figure) finds and reuses the same module
object, never initialised twice. `scipy.fft.fft(x, axis=-1, workers=w, overwrite_x=True)` is,
for a complex array, exactly `c2c(x, (axis,), True, 0, x, w)`, so the spectra are the same bit
for bit (tests/test_row_fft.py).

The extension is SciPy's private module: when it is missing, fails to load or does not pass a
4-point check of its call (a different SciPy), the public `scipy.fft.fft` is used instead, with
the same values and only the import cost back.
"""
from __future__ import annotations

import functools
import importlib.machinery
import importlib.util
import sys
import threading
from pathlib import Path
from typing import Callable

import numpy as np

_NAME = "scipy.fft._pocketfft.pypocketfft"

RowFft = Callable[[np.ndarray, int], np.ndarray]
_load_lock = threading.Lock()   # two threads' first FFTs must not both initialise the extension


def _extension_path() -> Path | None:
    """The pocketfft extension's file inside the installed SciPy (found without importing it)."""
    spec = importlib.util.find_spec("scipy")
    for root in (spec.submodule_search_locations or []) if spec else []:
        for suffix in importlib.machinery.EXTENSION_SUFFIXES:
            path = Path(root, "fft", "_pocketfft", "pypocketfft" + suffix)
            if path.is_file():
                return path
    return None


def _load_extension():
    """SciPy's pocketfft module: the one already imported, else loaded from its file (or None)."""
    if _NAME in sys.modules:
        return sys.modules[_NAME]
    if "scipy.fft" in sys.modules:  # SciPy has already paid its import: take its own module
        import scipy.fft._pocketfft.pypocketfft as ext
        return ext
    path = _extension_path()
    if path is None:
        return None
    spec = importlib.util.spec_from_file_location(_NAME, path)
    if spec is None or spec.loader is None:
        return None
    ext = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ext)
    sys.modules[_NAME] = ext
    return ext


def _passes_check(fft: RowFft) -> bool:
    """True when fft gives the forward, unnormalised DFT in place: [0, 1, 0, 0] -> [1, -i, -1, i]."""
    x = np.array([[0, 1, 0, 0]], np.complex64)
    y = fft(x, 1)
    return bool(y is x and np.array_equal(y, np.array([[1, -1j, -1, 1j]], np.complex64)))


def _extension_fft(ext) -> RowFft:
    def fft(frames: np.ndarray, workers: int) -> np.ndarray:
        return ext.c2c(frames, (frames.ndim - 1,), True, 0, frames, workers)
    return fft


def _public_fft(frames: np.ndarray, workers: int) -> np.ndarray:
    import scipy.fft
    return scipy.fft.fft(frames, axis=-1, workers=workers, overwrite_x=True)


@functools.cache
def row_fft_function() -> RowFft:
    """The function `row_fft` calls: pocketfft's own when it loads and checks out, else scipy.fft's."""
    try:
        with _load_lock:
            ext = _load_extension()
        if ext is not None:
            fft = _extension_fft(ext)
            if _passes_check(fft):
                return fft
    except (ImportError, OSError, AttributeError, TypeError, ValueError, RuntimeError):
        pass  # a SciPy laid out or called otherwise: the public function below
    return _public_fft


def row_fft(frames: np.ndarray, workers: int = 1) -> np.ndarray:
    """Forward DFT (unnormalised, e^{-2 pi i k n / N}) of each row of a C-contiguous complex
    array, written over `frames` and returned, on up to `workers` threads; the values are
    `scipy.fft.fft(frames, axis=-1)`'s bit for bit."""
    if frames.dtype.kind != "c" or not frames.flags.c_contiguous or not frames.flags.writeable:
        raise ValueError(f"row_fft needs a writable C-contiguous complex array, got {frames.dtype} "
                         f"(contiguous {frames.flags.c_contiguous}, writable {frames.flags.writeable})")
    return row_fft_function()(frames, workers)
