"""Rendering: frames during strokes (rgb_array_list, render_frames_per_stroke), the human window,
RecordStrokeVideo; rendering never changes a step."""
import math
import sys

import gymnasium as gym
import numpy as np
import pytest

from microconveyor_env.envs import MicroConveyorEnv
from microconveyor_env.envs.core import actions
from microconveyor_env.envs.line.frames import FrameState
from microconveyor_env.physics import dynamics_kernel as kernel
from microconveyor_env.physics.trajectory import Firing, Integration, firing_trajectory

SCHEDULE = (950.0, 200e-6, 2e-3)  # f [Hz], h [m], delay [s]: the part slides between strokes


def _episode(env, seed, acts):
    """Every step's (obs, reward, terminated, truncated, info) of one episode."""
    out = [env.reset(seed=seed, options={"target": 1.2e-3})]
    for a in acts:
        step = env.step(a)
        out.append(step)
        if step[2] or step[3]:
            break
    return out


def _same(a, b):
    assert len(a) == len(b)
    for ra, rb in zip(a, b, strict=True):
        for x, y in zip(ra, rb, strict=True):
            if isinstance(x, np.ndarray):
                assert x.dtype == y.dtype and np.array_equal(x, y)
            else:
                assert x == y and type(x) is type(y)


@pytest.mark.parametrize("kw", [{}, {"action_noise": 0.05, "friction_factor_range": (0.9, 1.1),
                                     "mass_factor_range": (0.9, 1.1)}])
def test_steps_identical_with_and_without_intra_stroke_rendering(kw):
    rng = np.random.default_rng(3)
    for seed in range(3):
        acts = rng.uniform(-1, 1, (5, 3)).astype(np.float32)
        plain = _episode(MicroConveyorEnv(**kw), seed, acts)
        env = MicroConveyorEnv(render_mode="rgb_array_list", render_frames_per_stroke=5, **kw)
        rendered = _episode(env, seed, acts)
        _same(plain, rendered)
        assert env._renderer.pending  # the frames were collected (drawn only at render())


def test_video_of_a_short_episode_has_more_frames_than_firings():
    env = gym.make("MicroConveyor-v0", render_mode="rgb_array_list", render_frames_per_stroke=4,
                   n_actuators=2)
    assert env.metadata["render_fps"] == 16 and type(env.unwrapped).metadata["render_fps"] == 4
    env.reset(seed=0, options={"target": 0.6e-3})
    a = actions.encode_actions(*SCHEDULE, env.unwrapped.config)
    frames, firings = env.render(), 0
    assert len(frames) == 1  # the start
    done = False
    while not done:
        _, _, term, trunc, _ = env.step(a)
        firings += 1
        done = term or trunc
        new = env.render()
        assert 2 <= len(new) <= 3 * 4 + 1  # stroke, slides, the end
        frames += new
    assert env.render() == []  # popped
    assert len(frames) > 3 * firings
    assert all(f.shape == frames[0].shape and f.dtype == np.uint8 for f in frames)
    assert len({f.tobytes() for f in frames}) > len(frames) // 2  # the picture moves


def test_frames_show_the_recorded_states_of_the_firing():
    env = MicroConveyorEnv(render_mode="rgb_array_list", render_frames_per_stroke=6)
    env.reset(seed=1, options={"target": 1e-3})
    before = (env.x, env.v, env.t)
    a = actions.encode_actions(*SCHEDULE, env.config)
    info = env.step(a)[-1]
    assert info["outcome"] == "moving"
    states = [s for s in env._renderer.pending if isinstance(s, FrameState)][1:]
    c = env.conveyor
    f, h, d = info["frequency_hz"], info["stroke_m"], info["delay_s"]  # as fired (float32 actions)
    traj = firing_trajectory(before, Firing(0.0, f, h, d),
                             Integration(c.consts.dt, c.consts.min_steps, False,
                                         env.config.max_time),
                             c.consts.P[0], (c.consts.tu, c.consts.tq, c.consts.tqu))
    rows = set(zip(traj.t_s.tolist(), traj.x_m.tolist(), strict=True))
    assert all((s.t, s.x) in rows for s in states)  # simulator states, never interpolated
    during = [s for s in states if s.firing == 0]
    assert len(during) == 6 and max(s.amplitude for s in during) > 0.5 * h
    assert all(s.t <= e.t for s, e in zip(states, states[1:], strict=False))


def test_firing_trajectory_ends_where_the_firing_ends():
    env = MicroConveyorEnv()
    c = env.conveyor
    rng = np.random.default_rng(0)
    for _ in range(20):
        f, h, d = rng.uniform(200, 8000), rng.uniform(100e-6, 200e-6), rng.uniform(0, 0.01)
        v0 = rng.choice([0.0, rng.uniform(-0.02, 0.05)])
        args = (-0.1e-3, v0, 0.0, 0.0, f, h, d, c.consts.dt, c.consts.min_steps, True,
                env.config.max_time, c.consts.P[0], c.consts.tu, c.consts.tq, c.consts.tqu)
        out = np.zeros(kernel.N_OUT)
        kernel.reset_out(out)
        x, v, t, code = kernel.fire(*args, np.zeros((0, kernel.N_REC)), out)
        traj = firing_trajectory(args[:3], Firing(*args[3:7]), Integration(*args[7:11]),
                                 args[11], args[12:])
        assert (traj.x, traj.v, traj.t, traj.outcome) == (x, v, t, code)
        assert np.all(np.diff(traj.t_s) >= 0) and traj.t_s.size >= 2
        assert traj.stroke_start_s == d


def test_default_render_is_todays():
    env = MicroConveyorEnv(render_mode="rgb_array_list")  # n = 1: what RenderCollection gives
    single = MicroConveyorEnv(render_mode="rgb_array")
    assert env.metadata["render_fps"] == 4 and env.render_frames_per_stroke == 1
    for e in (env, single):
        e.reset(seed=0)
    first = env.render()
    assert len(first) == 1 and np.array_equal(first[0], single.render())
    a = np.zeros(3, np.float32)
    env.step(a)
    single.step(a)
    frames = env.render()
    assert len(frames) == 1 and np.array_equal(frames[0], single.render())
    unwrapped = gym.make("MicroConveyor-v1", render_mode="rgb_array_list")
    assert unwrapped.unwrapped.render_mode == "rgb_array_list"  # native, no RenderCollection


@pytest.mark.parametrize("n, mode", [(0, "rgb_array_list"), (2.5, "rgb_array_list"),
                                     (True, "human"), (1001, "rgb_array_list"),
                                     (2, "rgb_array"), (2, None)])
def test_frames_per_stroke_refused(n, mode):
    with pytest.raises(ValueError, match="render_frames_per_stroke"):
        MicroConveyorEnv(render_mode=mode, render_frames_per_stroke=n)


def test_record_stroke_video_keeps_every_frame(tmp_path):
    pytest.importorskip("moviepy")
    from microconveyor_env.envs.core.video import RecordStrokeVideo

    env = gym.make("MicroConveyor-v0", render_mode="rgb_array_list", render_frames_per_stroke=3,
                   n_actuators=2)
    env = RecordStrokeVideo(env, str(tmp_path / "videos"), episode_trigger=lambda _: True,
                            disable_logger=True)
    env.reset(seed=0, options={"target": 0.6e-3})
    a = actions.encode_actions(*SCHEDULE, env.unwrapped.config)
    firings, done = 0, False
    while not done:
        _, _, term, trunc, _ = env.step(a)
        firings += 1
        done = term or trunc
    assert len(env.recorded_frames) > 3 * firings
    assert len(env.render()) == len(env.recorded_frames)  # RecordVideo's render() history
    env.close()
    assert [p.suffix for p in (tmp_path / "videos").iterdir()] == [".mp4"]


def test_human_mode_with_the_dummy_video_driver(monkeypatch):
    pytest.importorskip("pygame", reason="human mode needs pygame (the render extra)")
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    env = MicroConveyorEnv(render_mode="human", render_frames_per_stroke=2, n_actuators=2)
    env.metadata = {**env.metadata, "render_fps": 200}  # a fast test
    shown = []
    real = env._renderer.window.show
    monkeypatch.setattr(env._renderer.window, "show",
                        lambda frames, fps: (shown.append(len(frames)), real(frames, fps)))
    env.reset(seed=0)
    assert env._renderer.window.screen is not None and shown == [1]
    env.step(actions.encode_actions(*SCHEDULE, env.config))
    assert env.render() is None and len(shown) == 3 and shown[1] >= 2 and shown[2] == 0
    env.close()
    assert env._renderer.window.screen is None


def test_human_mode_without_pygame_names_the_extra(monkeypatch):
    from gymnasium.error import DependencyNotInstalled

    monkeypatch.setitem(sys.modules, "pygame", None)  # import pygame fails
    with pytest.raises(DependencyNotInstalled, match=r"microconveyor-env\[render\]"):
        MicroConveyorEnv(render_mode="human")


def test_first_frame_state_is_the_start():
    env = MicroConveyorEnv(render_mode="rgb_array_list", render_frames_per_stroke=3)
    env.reset(seed=0)
    (s,) = env._renderer.pending
    assert (s.t, s.x, s.amplitude, s.fired) == (0.0, env.x, 0.0, 0) and math.isnan(s.xa)


def test_pickles_mid_episode_with_frames_pending():
    import pickle

    env = MicroConveyorEnv(render_mode="rgb_array_list", render_frames_per_stroke=3)
    env.reset(seed=0, options={"target": 2.8e-3})
    a = actions.encode_actions(*SCHEDULE, env.config)
    env.step(a)
    env.render()  # the figure exists
    env.step(a)
    clone = pickle.loads(pickle.dumps(env))
    assert len(clone.render()) == len(env.render()) > 1
    _same([clone.step(a)], [env.step(a)])
