"""Per-episode randomisation of MicroConveyor-v0 (action noise, friction and mass factors)."""
import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from support import DATA
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


# ---------------------------------------------------------------------------- randomisation on
import gymnasium as gym  # noqa: E402

from microconveyor_env.envs import EnvConfig, MicroConveyorEnv, MicroConveyorVectorEnv  # noqa: E402
from microconveyor_env.envs.core import actions  # noqa: E402
from microconveyor_env.envs.core import randomisation  # noqa: E402
from microconveyor_env.physics import dynamics_kernel as kernel, forces  # noqa: E402
from microconveyor_env.physics.materials import G0  # noqa: E402
from support.lockstep import assert_lockstep_with_sync  # noqa: E402

RAND = {"action_noise": 0.1, "friction_factor_range": (0.6, 1.4),
        "mass_factor_range": (0.5, 2.0)}


def _rows(env, seed, acts):
    """(obs, reward, flags, info) of a single-env rollout through resets, as plain values."""
    obs, info = env.reset(seed=seed)
    out = [(obs.tolist(), info)]
    for a in acts:
        obs, r, te, tr, info = env.step(a)
        out.append((obs.tolist(), r, te, tr, info))
        if te or tr:
            obs, info = env.reset()
            out.append((obs.tolist(), info))
    return out


def test_defaults_are_off_and_add_nothing():
    cfg = EnvConfig()
    assert cfg.action_noise == 0.0 and cfg.friction_factor_range == (1.0, 1.0)
    assert cfg.mass_factor_range == (1.0, 1.0) and not cfg.randomised
    env = MicroConveyorEnv()
    _, info = env.reset(seed=0)
    assert "friction_factor" not in info and "mass_factor" not in info
    assert env.np_random.bit_generator.seed_seq.n_children_spawned == 0
    assert EnvConfig(action_noise=1e-9).randomised and EnvConfig(mass_factor_range=(1, 1.1)).randomised


def test_randomisation_on_is_reproducible_with_a_seed():
    acts = np.random.default_rng(0).uniform(-1, 1, (15, 3)).astype(np.float32)
    a = _rows(MicroConveyorEnv(**RAND), 7, acts)
    b = _rows(MicroConveyorEnv(**RAND), 7, acts)
    assert a == b
    c = _rows(MicroConveyorEnv(**RAND), 8, acts)
    assert c[0][1]["friction_factor"] != a[0][1]["friction_factor"]
    # factors change from episode to episode
    resets = [r[-1] for r in a if len(r) == 2]
    assert len({info["mass_factor"] for info in resets}) == len(resets) >= 3


def test_randomisation_leaves_the_start_and_target_draws_alone():
    """The draws come from derived streams: start and targets are those of the env without."""
    kw = {"start_jitter": 40e-6}
    plain, rand = MicroConveyorEnv(**kw), MicroConveyorEnv(**kw, **RAND)
    for seed in (0, 1, 2):
        o1, _ = plain.reset(seed=seed)
        o2, _ = rand.reset(seed=seed)
        np.testing.assert_array_equal(o1, o2)
        for _ in range(3):  # later episodes too (np_random is not drawn from by the options)
            np.testing.assert_array_equal(plain.reset()[0], rand.reset()[0])


@pytest.mark.parametrize("mode,threads", [(gym.vector.AutoresetMode.NEXT_STEP, 1),
                                          (gym.vector.AutoresetMode.SAME_STEP, 2)])
def test_single_env_equals_batched_env_part_for_part_with_randomisation(mode, threads):
    kw = {"start_jitter": 30e-6, "n_actuators": 3, **RAND}
    batched = MicroConveyorVectorEnv(4, autoreset_mode=mode, num_threads=threads, **kw)
    assert assert_lockstep_with_sync(batched, kw, 11, 14, 5, 1.2, mode) >= 4
    _, info = batched.reset(seed=11)
    assert "friction_factor" in info and "mass_factor" in info


def test_factors_stay_in_their_ranges_and_are_spread_over_them():
    env = MicroConveyorVectorEnv(400, num_threads=1, friction_factor_range=(0.8, 1.25),
                                 mass_factor_range=(0.5, 2.0))
    _, info = env.reset(seed=0)
    ff, mf = info["friction_factor"], info["mass_factor"]
    np.testing.assert_array_equal(ff, env.friction_factor)
    assert ff.min() >= 0.8 and ff.max() <= 1.25 and mf.min() >= 0.5 and mf.max() <= 2.0
    assert ff.min() < 0.81 and ff.max() > 1.24 and mf.min() < 0.52 and mf.max() > 1.98
    assert abs(np.corrcoef(ff, mf)[0, 1]) < 0.2  # independent draws
    # the part's row of constants carries them
    P = env.conveyor.consts.P
    np.testing.assert_array_equal(P[:, forces.I_MASS], env.sim.params[forces.I_MASS] * mf)
    np.testing.assert_array_equal(P[:, forces.I_FSCALE], ff)
    # a degenerate range gives exactly its value
    one = MicroConveyorEnv(friction_factor_range=(0.7, 0.7), mass_factor_range=(1.0, 1.0))
    _, info = one.reset(seed=1)
    assert info["friction_factor"] == 0.7 and info["mass_factor"] == 1.0


def _fired(env, seed, acts):
    env.reset(seed=seed)
    out = []
    for a in acts:
        _, _, te, tr, info = env.step(a)
        out.append((info["frequency_hz"], info["stroke_m"], info["delay_s"]))
        if te or tr:
            break
    return out


def test_action_noise_zero_is_exactly_off_and_info_shows_the_noisy_firing():
    acts = np.array([[0.2, -0.3, -0.95], [0.9, 0.1, -1.0], [0.0, 0.0, -0.9]], np.float32)
    cfg = EnvConfig(n_actuators=3)
    given = [actions.decode(*a.astype(float), actions.constants(cfg)) for a in acts]
    quiet = _fired(MicroConveyorEnv(n_actuators=3, mass_factor_range=(0.9, 1.1)), 0, acts)
    assert quiet == given[:len(quiet)]  # sigma = 0: the given action, bit for bit
    env = MicroConveyorEnv(n_actuators=3, action_noise=0.05)
    noisy = _fired(env, 0, acts)
    z = env.conveyor.consts.noise[0]
    for k, fired in enumerate(noisy):
        expected = actions.decode(*(acts[k].astype(float) + 0.05 * z[k]), actions.constants(cfg))
        assert fired == expected and fired != given[k]
    # the noise is clipped to the box: full-scale actions never fire beyond the ranges
    env = MicroConveyorEnv(n_actuators=3, action_noise=0.5)
    for seed in range(5):
        for f, h, d in _fired(env, seed, np.ones((3, 3), np.float32)):
            assert f <= cfg.freq_range[1] and h <= cfg.stroke_range[1] and d <= cfg.delay_range[1]


def test_action_noise_has_the_configured_sigma():
    sigma, n = 0.1, 300
    cfg = EnvConfig(n_actuators=1, action_noise=sigma, num_threads=1)
    env = MicroConveyorVectorEnv(n, config=cfg)
    env.reset(seed=3)
    a = np.zeros((n, 3), np.float32)
    _, _, _, _, info = env.step(a)
    fired = actions.encode_actions(info["frequency_hz"], info["stroke_m"], info["delay_s"], cfg)
    assert np.std(fired, axis=0) == pytest.approx([sigma] * 3, rel=0.15)
    assert np.abs(np.mean(fired, axis=0)).max() < 4 * sigma / np.sqrt(n)


def _coast_distance(P_row, tables, v0=0.02):
    x, v, _, rest, _ = kernel.coast(0.0, v0, np.inf, P_row, *tables)
    assert rest and v == 0.0
    return x


def test_less_friction_or_more_mass_lets_a_sliding_part_travel_farther():
    """A part sliding at v0 on the still, flat surface stops after v0^2 / (2 a) with the
    deceleration a = f_f Q(m_f m g) / (m_f m): the env's per-part constants carry both factors."""
    dists = {}
    for ff, mf in ((1.0, 1.0), (0.5, 1.0), (2.0, 1.0), (1.0, 2.0)):
        env = MicroConveyorEnv(friction_factor_range=(ff, ff), mass_factor_range=(mf, mf))
        env.reset(seed=0)
        m = env.sim.mass * mf
        a = ff * float(env.sim.table.friction(m * G0)) / m
        dists[ff, mf] = d = _coast_distance(env.conveyor.consts.P[0], env.sim.tables)
        assert d == pytest.approx(0.02 ** 2 / (2 * a), rel=1e-9)
    assert dists[0.5, 1.0] > dists[1.0, 1.0] > dists[2.0, 1.0]
    assert dists[0.5, 1.0] == pytest.approx(2 * dists[1.0, 1.0], rel=1e-12)
    assert dists[1.0, 2.0] > 1.9 * dists[1.0, 1.0]  # adhesion-dominated Q: ~ twice as far


def test_friction_factor_moves_the_whole_episode_in_the_expected_direction():
    """Same firings, same seed: with less friction the part slides farther after each stroke,
    so it ends farther downstream (this schedule pushes it downstream)."""
    a = actions.encode_actions(950.0, 180e-6, 0.0, EnvConfig())
    ends = []
    for ff in (0.7, 1.0, 1.4):
        env = MicroConveyorEnv(friction_factor_range=(ff, ff))
        env.reset(seed=0, options={"target": 3e-3})
        for _ in range(5):
            _, _, te, tr, info = env.step(a)
            if te or tr:
                break
        assert info["outcome"] == "rest"
        ends.append(env.x)
    assert ends[0] > ends[1] > ends[2]


@pytest.mark.parametrize("kw,field", [
    ({"action_noise": -0.1}, "action_noise"), ({"action_noise": 1.5}, "action_noise"),
    ({"action_noise": float("nan")}, "action_noise"), ({"action_noise": "0.1"}, "action_noise"),
    ({"friction_factor_range": (0.05, 1.0)}, r"friction_factor_range\[0\]"),
    ({"friction_factor_range": (1.0, 20.0)}, r"friction_factor_range\[1\]"),
    ({"friction_factor_range": (1.5, 1.0)}, "friction_factor_range"),
    ({"friction_factor_range": [1.0]}, "friction_factor_range"),
    ({"mass_factor_range": (0.0, 1.0)}, r"mass_factor_range\[0\]"),
    ({"mass_factor_range": (1.0, 11.0)}, r"mass_factor_range\[1\]"),
    ({"mass_factor_range": (1.0, 5.0), "freq_range": [200.0, 50000.0]}, "mass_factor_range"),
])
def test_bad_randomisation_values_name_the_field_and_the_range(kw, field):
    with pytest.raises(ValueError, match=field) as exc:
        gym.make("MicroConveyor-v0", **kw)
    msg = str(exc.value)
    if "[0]" in field or "[1]" in field:
        assert "[0.1, 10]" in msg
    if field == "action_noise":
        assert "[0, 1]" in msg
    if "freq_range" in kw:
        assert "contact table" in msg


def test_the_repositorys_yaml_documents_the_options_with_the_dataclass_defaults():
    """By path: an editable install may map the package's configs to another checkout."""
    path = Path(__file__).parents[2] / "configs" / "envs" / "MicroConveyor-v0.yaml"
    assert EnvConfig.from_yaml(str(path)) == EnvConfig()
    text = path.read_text()
    for key in ("action_noise:", "friction_factor_range:", "mass_factor_range:"):
        assert key in text


def test_from_yaml_reads_the_options():
    cfg = EnvConfig.from_yaml(action_noise=0.05, friction_factor_range=[0.8, 1.2],
                              mass_factor_range=[0.9, 1.1])
    assert cfg.friction_factor_range == (0.8, 1.2) and cfg.mass_factor_range == (0.9, 1.1)
    assert cfg.randomised


def test_streams_are_derived_without_drawing_from_the_generator():
    rng = np.random.default_rng(42)
    before = rng.bit_generator.state
    s1 = randomisation.streams(rng)
    assert rng.bit_generator.state == before
    s2 = randomisation.streams(np.random.default_rng(42))
    assert s1[0].random() == s2[0].random() and s1[1].random() == s2[1].random()
    assert s1[0].random() != s1[1].random()
    restored = np.random.Generator(np.random.PCG64())
    restored.bit_generator.state = before  # no seed sequence of its own: a hash of the state
    assert randomisation.streams(restored)[0].random() == randomisation.streams(restored)[0].random()


def test_sb3_adapter_passes_the_options_and_reports_the_factors():
    pytest.importorskip("stable_baselines3")
    from microconveyor_env.envs.core.sb3 import MicroConveyorSB3VecEnv

    def first(seed, **kw):
        env = MicroConveyorSB3VecEnv(3, n_actuators=2, **kw)
        env.seed(seed)
        obs = env.reset()
        return env, obs

    env, _ = first(4, **RAND)
    assert env.venv.config.action_noise == 0.1 and env.venv.config.mass_factor_range == (0.5, 2.0)
    ff = [info["friction_factor"] for info in env.reset_infos]
    assert all(0.6 <= f <= 1.4 for f in ff)
    assert ff == [i["friction_factor"] for i in first(4, **RAND)[0].reset_infos]
    # seeds as the single env: sub-env i seeded 4 + i
    single = MicroConveyorEnv(n_actuators=2, **RAND)
    assert ff == [single.reset(seed=4 + i)[1]["friction_factor"] for i in range(3)]
    current, ended = list(ff), 0
    for _ in range(6):
        obs, rew, dones, infos = env.step(np.zeros((3, 3), np.float32))
        for i in np.flatnonzero(dones):
            assert infos[i]["friction_factor"] == current[i]  # the finished episode's factor
            current[i] = env.reset_infos[i]["friction_factor"]  # and the new episode's
            assert "mass_factor" in env.reset_infos[i] and "terminal_observation" in infos[i]
            ended += 1
    assert ended >= 3 and current != ff
    cfg = EnvConfig(n_actuators=2, **RAND)
    env = MicroConveyorSB3VecEnv(2, config=cfg)
    env.reset()
    assert set(env.reset_infos[0]) >= {"friction_factor", "mass_factor"}
    plain, _ = first(4)
    assert "friction_factor" not in plain.reset_infos[0]


def test_checkers_and_pickle_with_randomisation_on(monkeypatch):
    import pickle
    import warnings

    from support.checkers import gymnasium_check_env

    with warnings.catch_warnings():  # Gymnasium's note that v0 has a successor is expected here
        warnings.filterwarnings("ignore", message=".*MicroConveyor-v0 is out of date",
                                category=DeprecationWarning)
        env = gym.make("MicroConveyor-v0", **RAND).unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gymnasium_check_env(env, monkeypatch)
    env = MicroConveyorEnv(**RAND)
    env.reset(seed=3)
    _, _, te, tr, _ = env.step(np.array([0.1, 0.5, -0.9], np.float32))
    if te or tr:
        env.reset()
    clone = pickle.loads(pickle.dumps(env))
    acts = np.random.default_rng(1).uniform(-1, 1, (9, 3)).astype(np.float32)
    for a in acts:
        s1, s2 = env.step(a), clone.step(a)
        np.testing.assert_array_equal(s1[0], s2[0])
        assert s1[1:] == s2[1:]
        if s1[2] or s1[3]:
            r1, r2 = env.reset(), clone.reset()
            np.testing.assert_array_equal(r1[0], r2[0])
            assert r1[1] == r2[1]
