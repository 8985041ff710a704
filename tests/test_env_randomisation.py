"""Per-episode randomisation of MicroConveyor-v0 (action noise, friction and mass factors)."""
import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).parent / "data"
_spec = importlib.util.spec_from_file_location("make_rollouts_v0", DATA / "make_rollouts_v0.py")
rec = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(rec)
STORED = json.loads((DATA / "rollouts_v0.json").read_text())


@pytest.mark.parametrize("name", sorted(STORED["single"]))
def test_randomisation_off_replays_the_stored_single_env_rollouts_bit_for_bit(name):
    case = STORED["single"][name]
    acts = np.array(case["actions"]).astype(np.float32)
    assert rec.record_single(case["config"], case["seed"], acts) == case["rows"]


@pytest.mark.parametrize("name", sorted(STORED["batched"]))
def test_randomisation_off_replays_the_stored_batched_rollouts_bit_for_bit(name):
    case = STORED["batched"][name]
    acts = np.array(case["actions"]).astype(np.float32)
    assert rec.record_batched(case["config"], case["seed"], case["num_envs"], acts) == case["rows"]
