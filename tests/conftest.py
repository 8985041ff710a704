import os

import pytest


@pytest.fixture(scope="session", autouse=True)
def _isolated_cache(tmp_path_factory):
    """Keep the test run's contact tables out of the user's cache directory."""
    old = os.environ.get("MICROCONVEYOR_CACHE_DIR")
    os.environ["MICROCONVEYOR_CACHE_DIR"] = str(tmp_path_factory.mktemp("cache"))
    yield
    if old is None:
        os.environ.pop("MICROCONVEYOR_CACHE_DIR", None)
    else:
        os.environ["MICROCONVEYOR_CACHE_DIR"] = old


@pytest.fixture(scope="session")
def seed():
    from microconveyor_env.presets import load_preset

    return load_preset("seed")


@pytest.fixture(scope="session")
def seed_table(seed):
    from microconveyor_env.physics.contact_table import ContactTable

    return ContactTable(seed.contact)
