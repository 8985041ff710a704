"""The conveyor state the single and the batched env share (envs/line/state.py, envs/line/step.py)."""
import ast
import pickle
from pathlib import Path

import numpy as np
import pytest

from microconveyor_env.envs import MicroConveyorEnv, MicroConveyorVectorEnv
from microconveyor_env.envs.line import step
from microconveyor_env.envs.line.state import Conveyor
from microconveyor_env.physics import forces
from microconveyor_env.physics.contact_table import TableRangeError

ENVS = Path(step.__file__).resolve().parent


def test_both_envs_delegate_to_one_conveyor_state():
    single = MicroConveyorEnv(n_actuators=3)
    batched = MicroConveyorVectorEnv(3, n_actuators=3, num_threads=1)
    assert isinstance(single.conveyor, Conveyor) and single.conveyor.n == 1
    assert isinstance(batched.conveyor, Conveyor) and batched.conveyor.n == 3
    parts = batched.conveyor.parts
    assert (batched.x is parts.x and batched.v is parts.v and batched.t is parts.t
            and batched.fired is parts.fired and batched.target is parts.target)
    assert batched.threads is batched.conveyor.threads and batched.sim is batched.conveyor.sim
    single.reset(seed=4)
    batched.reset(seed=4)
    assert single.x == batched.x[0] and single.target == batched.target[0]
    assert single.conveyor.threads.fixed == 1  # the single env always runs the serial loop


def test_vector_env_imports_no_helper_from_the_single_env():
    tree = ast.parse((ENVS / "vector.py").read_text())
    sources = {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    assert "env" not in sources and "rail.parts" in sources and "state" in sources


@pytest.mark.parametrize("num_threads", [1, 2])
def test_calls_go_straight_to_the_compiled_code_and_pickle(num_threads):
    """After the first step the compiled calls bypass numba's dispatcher (its type resolution
    of the NamedTuples costs more than the rest of a step's Python); pickling drops them and
    the clone rebuilds them, same results."""
    env = MicroConveyorVectorEnv(4, n_actuators=3, num_threads=num_threads)
    env.reset(seed=2)
    acts = np.random.default_rng(0).uniform(-1, 1, (6, 4, 3))
    env.step(acts[0])
    call = env.conveyor._serial if num_threads == 1 else env.conveyor._parallel
    assert call.entry is not None and call.entry is not call.fn
    clone = pickle.loads(pickle.dumps(env))
    assert clone.conveyor._serial.entry is None and clone.conveyor._parallel.entry is None
    assert clone.conveyor._serial.args[2] is clone.conveyor.parts
    for a in acts[1:]:
        s1, s2 = env.step(a), clone.step(a)
        for u, w in zip(s1[:4], s2[:4], strict=True):
            np.testing.assert_array_equal(u, w)
    assert clone.x is clone.conveyor.parts.x  # the clone's arrays are its state's


def _shrink_table(conveyor, i):
    conveyor.consts.P[i, forces.I_NMAX] = conveyor.consts.P[i, forces.I_NMIN] + 1e-12


@pytest.mark.parametrize("num_threads", [None, 1, 2])
def test_a_load_beyond_the_table_raises(num_threads):
    """The compiled step counts the parts whose load left the contact table; either env raises
    (the construction-time check makes this unreachable with a sound table)."""
    if num_threads is None:
        env = MicroConveyorEnv()
        env.reset(seed=0)
        _shrink_table(env.conveyor, 0)
        with pytest.raises(TableRangeError, match="left the contact table"):
            env.step(np.array([0.5, 1.0, -1.0], np.float32))
        return
    venv = MicroConveyorVectorEnv(4, num_threads=num_threads)
    venv.reset(seed=0)
    _shrink_table(venv.conveyor, 2)
    with pytest.raises(TableRangeError, match="left the contact table"):
        venv.step(np.tile([0.5, 1.0, -1.0], (4, 1)))


def test_set_targets_gives_the_observation_a_reset_with_that_target_gives():
    from microconveyor_env.envs import env_config

    cfg = env_config("MicroConveyor-v1", num_threads=1)
    a = MicroConveyorVectorEnv(3, config=cfg)
    b = MicroConveyorVectorEnv(3, config=cfg)
    a.reset(seed=2)
    obs_b, _ = b.reset(seed=2, options={"target": np.array([1e-3, 4e-3, 7e-3])})
    np.testing.assert_array_equal(a.set_targets([0, 1, 2], [1e-3, 4e-3, 7e-3]), obs_b)
    a.step(np.zeros((3, 3), np.float32))
    with pytest.raises(ValueError, match="only at an episode's start"):
        a.set_targets([1], [2e-3])
    with pytest.raises(ValueError, match="invalid"):
        b.set_targets([0], [np.nan])
    with pytest.raises(IndexError):
        b.set_targets([3], [1e-3])
