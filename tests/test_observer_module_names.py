"""Design claim (audit G1 of issue 14): each registered observer lives in the module named after it,
``fawtgym.observers.<registry name>`` (observers/<name>.py)."""

from __future__ import annotations

import pytest

from fawtgym.observers import observer_names
from fawtgym.observers.base import observer_class


@pytest.mark.parametrize("name", observer_names())
def test_registry_name_is_the_module_name(name):
    assert observer_class(name).__module__ == f"fawtgym.observers.{name}"
