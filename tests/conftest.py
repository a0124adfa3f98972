"""Fixtures shared by every test folder."""

from __future__ import annotations

import pytest
from hapticdesk.profile import DeskProfile, load_profile


@pytest.fixture(scope="session")
def paper_desk() -> DeskProfile:
    """The paper's desk (profiles/kitamura2017.yaml)."""
    return load_profile("kitamura2017")
