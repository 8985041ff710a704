"""The batched env's resets of many sub-envs at once (autoreset, a seeded reset) draw exactly what
one reset per sub-env draws, and the scalar uniform draws of the starts and targets are
``Generator.uniform``'s bit for bit."""
import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils import seeding

from microconveyor_env.envs import EnvConfig, MicroConveyorVectorEnv
from microconveyor_env.envs.core import randomisation
from microconveyor_env.envs.line.state import Conveyor
from microconveyor_env.envs.plane import task as plane_task
from microconveyor_env.envs.plane.config import PlaneEnvConfig
from microconveyor_env.envs.rail.parts import initial_state, initial_states
from support.lockstep import assert_lockstep_with_sync

RAND = {"action_noise": 0.1, "friction_factor_range": (0.6, 1.4),
        "mass_factor_range": (0.5, 2.0)}
RANGES = [(0.5e-3, 3.0e-3), (-1.0, 1.0), (0.1, 10.0), (-2e-3, 7e-3), (1e-6, 1.0000001e-6),
          (0.8, 1.2), (0.0, 0.1)]


def _generators(seeds):
    """The generators the envs draw from (gymnasium's seeding, as the batched env's)."""
    return [seeding.np_random(s)[0] for s in seeds]


@pytest.mark.parametrize("lo,hi", RANGES)
def test_uniform_is_the_generators_uniform_bit_for_bit(lo, hi):
    mine, ref = _generators(range(20)), _generators(range(20))
    for a, b in zip(mine, ref, strict=True):
        got = [randomisation.uniform(a, lo, hi) for _ in range(300)]
        assert got == [float(b.uniform(lo, hi)) for _ in range(300)]
        assert a.bit_generator.state == b.bit_generator.state  # the same numbers drawn


def _rail_reference(cfg, rng, target=None):
    """The rail's start and target as Generator.uniform draws them."""
    jitter = rng.uniform(-1.0, 1.0) * cfg.start_jitter if cfg.start_jitter else 0.0
    drawn = rng.uniform(*cfg.target_range)
    return -cfg.start_offset + jitter, drawn if target is None else target


@pytest.mark.parametrize("jitter", [0.0, 40e-6])
def test_rail_starts_and_targets_are_the_generators_uniform_draws(jitter):
    cfg = EnvConfig(start_jitter=jitter, target_range=(0.7e-3, 2.9e-3))
    seeds = range(64)
    ref = [_rail_reference(cfg, g) for g in _generators(seeds)]
    one = [initial_state(cfg, g) for g in _generators(seeds)]
    x0, tgt = initial_states(cfg, _generators(seeds))
    assert one == ref
    assert list(zip(x0.tolist(), tgt.tolist(), strict=True)) == ref
    assert initial_state(cfg, _generators([5])[0], 1e-3)[1] == 1e-3


def test_plane_starts_and_targets_are_the_generators_uniform_draws():
    cfg = PlaneEnvConfig(start_jitter=50e-6)
    for a, b in zip(_generators(range(32)), _generators(range(32)), strict=True):
        (x0, x1), (y0, y1) = cfg.grid_box
        tx, ty = b.uniform(x0, x1), b.uniform(y0, y1)
        sx = cfg.start[0] + b.uniform(-1.0, 1.0) * cfg.start_jitter
        sy = cfg.start[1] + b.uniform(-1.0, 1.0) * cfg.start_jitter
        assert plane_task.initial_state(cfg, a) == (sx, sy, tx, ty)


def _arrays(c):
    return {"x": c.parts.x, "v": c.parts.v, "t": c.parts.t, "fired": c.parts.fired,
            "target": c.parts.target, "P": c.consts.P, "noise": c.consts.noise, "obs": c.obs,
            "friction_factor": c.friction_factor, "mass_factor": c.mass_factor}


@pytest.mark.parametrize("kw", [{}, {"start_jitter": 30e-6, "observe_history": 2, **RAND},
                                {"friction_factor_range": (0.9, 1.1)}])
def test_reset_parts_equals_reset_part_part_by_part(kw):
    cfg = EnvConfig(n_actuators=3, **kw)
    n = 7
    one, many = Conveyor(cfg, n), Conveyor(cfg, n)
    for c in (one, many):  # something in every row that a reset must overwrite
        for arr in _arrays(c).values():
            arr[...] = 3
    g1, g2 = _generators(range(100, 100 + n)), _generators(range(100, 100 + n))
    for rows in (np.arange(n), np.array([1, 4, 5]), np.array([0, 6])):
        for i in rows.tolist():
            one.reset_part(i, g1[i])
        many.reset_parts(rows, [g2[i] for i in rows.tolist()])
        for key, arr in _arrays(one).items():
            np.testing.assert_array_equal(_arrays(many)[key], arr, err_msg=key)
        assert [g.bit_generator.state for g in g1] == [g.bit_generator.state for g in g2]


@pytest.mark.parametrize("mode,threads", [(gym.vector.AutoresetMode.NEXT_STEP, 2),
                                          (gym.vector.AutoresetMode.SAME_STEP, 1)])
def test_batched_autoresets_equal_sync_vector_env_with_randomisation_and_history(mode, threads):
    """Many sub-envs end in the same step (short episodes), with randomisation, start jitter and
    the observation history on; then a reset with a new seed (new streams) and more."""
    kw = {"start_jitter": 30e-6, "n_actuators": 2, "observe_history": 1, **RAND}
    batched = MicroConveyorVectorEnv(9, autoreset_mode=mode, num_threads=threads, **kw)
    assert assert_lockstep_with_sync(batched, kw, 21, 12, 4, 1.0, mode) >= 12
    assert assert_lockstep_with_sync(batched, kw, 40, 8, 6, 1.0, mode) >= 8
