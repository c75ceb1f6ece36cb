"""Package layout: the repository keeps `models/ codegen/ hardware/` at its top, and installs
them as `leonav.models`, `leonav.codegen`, `leonav.hardware` (no top-level import names that a
user's own `models` or `hardware` package could collide with). Everything else is in
pyproject.toml; the package lists are found here so that a new subpackage needs no edit."""
from setuptools import find_packages, setup

INSTALLED_AS = {"models": "leonav.models", "codegen": "leonav.codegen", "hardware": "leonav.hardware"}

packages = ["leonav"] + [p for p in find_packages(include=["leonav_runtime", "leonav_runtime.*"])]
package_dir = {}
for folder, name in INSTALLED_AS.items():
    package_dir[name] = folder
    packages += [name] + [f"{name}.{sub}" for sub in find_packages(folder)]

setup(packages=packages, package_dir=package_dir)
