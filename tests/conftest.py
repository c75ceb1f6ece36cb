"""Shared test fixtures.

`shared_data` points at ../shared/data (real public fixtures, read in place, never
copied). Tests that need it skip with a clear reason when it is absent.
"""
from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("LEONAV_SHARED_DATA", REPO_ROOT.parent / "shared" / "data"))


def shared_file(relative: str) -> Path:
    """Path of a file under ../shared/data; skips the calling test if it is missing."""
    path = SHARED_DATA / relative
    if not path.exists():
        pytest.skip(f"needs ../shared/data/{relative} (real public fixture, see SOURCES.md); not found at {path}")
    return path


@pytest.fixture
def shared_data() -> Path:
    """The ../shared/data folder; skips when absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"needs ../shared/data (real public fixtures); not found at {SHARED_DATA}")
    return SHARED_DATA
