"""Helpers the tests share (on ``sys.path`` through pytest's ``pythonpath = ["tests"]``):
``support.dynamics`` (simulators and constants of the dynamics tests), ``support.plane``
(the plane's simulators and scenes), ``support.lockstep``
(batched env against SyncVectorEnv), ``support.fingerprint_child`` (table and rollout hashes in a
child process), ``support.checkers`` (Gymnasium's env checker, headless, without pygame),
``support.snippets`` (documentation code blocks run as tests), ``support.scripts``
(``scripts/*.py`` loaded as modules), ``support.cli`` (the ``microconveyor`` command run in the
test's process). ``DATA`` is the folder of stored test data."""
from pathlib import Path

DATA = Path(__file__).resolve().parents[1] / "data"
