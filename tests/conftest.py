import os

import pytest

TABLES = "MICROCONVEYOR_TEST_TABLES"   # the run's contact-table folder, set where the run starts


@pytest.hookimpl(trylast=True)   # after pytest's own configure (its temporary folders)
def pytest_configure(config):
    """Where the run starts (the xdist controller, or the one process of ``-n 0``): one
    contact-table folder for the whole run, which the workers inherit through the environment
    (:func:`_isolated_cache`)."""
    if hasattr(config, "workerinput"):
        return
    tables = config._tmp_path_factory.getbasetemp() / "tables"
    tables.mkdir(exist_ok=True)
    os.environ[TABLES] = str(tables)


def pytest_unconfigure(config):
    if not hasattr(config, "workerinput"):
        os.environ.pop(TABLES, None)


@pytest.fixture(scope="session", autouse=True)
def _isolated_cache(tmp_path_factory):
    """Keep the test run's contact tables out of the user's cache directory: in one folder for
    the whole run, shared by the workers (the cache writes each table whole, atomically, so two
    workers building the same table leave one good file; tests of the cache itself use folders
    of their own)."""
    old = os.environ.get("MICROCONVEYOR_CACHE_DIR")
    os.environ["MICROCONVEYOR_CACHE_DIR"] = (os.environ.get(TABLES)
                                             or str(tmp_path_factory.mktemp("cache")))
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
