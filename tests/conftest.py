"""Test-session settings: the frame cache of `monorarp sweep` / `bench trackers` lives in a temporary directory."""

from __future__ import annotations

import pytest


@pytest.fixture(autouse=True, scope="session")
def _frame_cache_dir(tmp_path_factory):
    """Never fill the user's ~/.cache from tests (``MONORARP_CACHE_DIR``, see harness.run.frame_cache)."""
    mp = pytest.MonkeyPatch()
    mp.setenv("MONORARP_CACHE_DIR", str(tmp_path_factory.mktemp("frame_cache")))
    yield
    mp.undo()
