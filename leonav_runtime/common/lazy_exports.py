"""Package namespaces whose names are imported from their modules on first use (PEP 562).

A command's parser imports the package of its command (e.g. `leonav_runtime.replay` for the
mode names); with eager `from .x import *` in the package's `__init__` every `leonav`
invocation paid for all of them (SciPy through the simulator, the HTTP client through the
element fetcher). `lazy_exports` keeps `from leonav_runtime.replay import replay_session`
and `leonav_runtime.replay.report` working while importing only what is used.
"""
from __future__ import annotations

import importlib
import importlib.util
from typing import Callable


def lazy_exports(package: str, exports: dict[str, tuple[str, ...]]) -> tuple[list[str], Callable, Callable]:
    """(`__all__`, `__getattr__`, `__dir__`) of `package` whose names are `exports`
    (submodule -> names in it); a submodule's own name resolves to the submodule."""
    where = {name: module for module, names in exports.items() for name in names}
    names = [name for group in exports.values() for name in group]
    namespace = importlib.import_module(package).__dict__

    def __getattr__(name: str):
        module = where.get(name)
        if module is None:
            if name.startswith("__") or importlib.util.find_spec(f"{package}.{name}") is None:
                raise AttributeError(f"module {package!r} has no attribute {name!r}")
            return importlib.import_module(f"{package}.{name}")
        value = getattr(importlib.import_module(f"{package}.{module}"), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(names))

    return names, __getattr__, __dir__
