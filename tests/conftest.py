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


@pytest.fixture(scope="session", autouse=True)
def _isolated_tmp(tmp_path_factory):
    """Temporary files of the run (SB3's default logger makes a ``SB3-<date>`` folder in the
    temp dir for every model that learns without one, and the CLI subprocesses inherit
    ``TMPDIR``) go to pytest's own temporary tree, not the machine's /tmp."""
    import tempfile

    old_env, old_dir = os.environ.get("TMPDIR"), tempfile.tempdir
    tmp = str(tmp_path_factory.mktemp("tmp"))
    os.environ["TMPDIR"] = tmp
    tempfile.tempdir = tmp
    yield
    tempfile.tempdir = old_dir
    if old_env is None:
        os.environ.pop("TMPDIR", None)
    else:
        os.environ["TMPDIR"] = old_env


@pytest.fixture(scope="session")
def feasibility_preset():
    from microconveyor_env.presets import load_preset

    return load_preset("feasibility")


@pytest.fixture(scope="session")
def feasibility_table(feasibility_preset):
    from microconveyor_env.physics.contact_table import ContactTable

    return ContactTable(feasibility_preset.contact)


@pytest.fixture(scope="session")
def dask_client(_isolated_cache):
    """A local Dask cluster of 2 single-threaded worker processes, started once per session (the
    studies' parallel = serial tests); the workers inherit the isolated cache directory."""
    distributed = pytest.importorskip("distributed")
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       dashboard_address=":0")
    client = distributed.Client(cluster)
    yield client
    client.close()
    cluster.close()
