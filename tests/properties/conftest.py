"""Hypothesis profiles for the property suite.

``quick`` (the default) keeps the default test run fast. ``thorough`` is loaded when the run
selects slow tests (``pytest -m slow``): the property tests then count as slow too, so they run
with many more examples. ``HYPOTHESIS_PROFILE=thorough`` forces it.
"""
import os

import pytest
from hypothesis import HealthCheck, settings

_COMMON = dict(deadline=None, print_blob=True,
               suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                      HealthCheck.function_scoped_fixture])
settings.register_profile("quick", max_examples=25, **_COMMON)
settings.register_profile("thorough", max_examples=400, **_COMMON)


def _thorough(config) -> bool:
    expr = config.getoption("markexpr") or ""
    return os.environ.get("HYPOTHESIS_PROFILE") == "thorough" or (
        "slow" in expr and "not slow" not in expr)


def pytest_configure(config):
    settings.load_profile("thorough" if _thorough(config) else "quick")


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    if not _thorough(config):
        return
    here = os.path.dirname(__file__)
    for item in items:
        if str(item.fspath).startswith(here) and hasattr(item.obj, "hypothesis"):
            item.add_marker(pytest.mark.slow)
