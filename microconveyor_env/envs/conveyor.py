"""MicroConveyor-v0: carry a micropart to a target with a linear array of micro-actuators."""
from __future__ import annotations

import math
import numbers

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from ..physics import dynamics_kernel as kernel
from ..physics.contact_table import TableRangeError
from ..physics.materials import ParameterError
from ..physics.simulator import Simulator
from ..presets import simulator
from . import actions, randomisation, step as kstep, task
from .config import EnvConfig


def make_simulator(cfg: EnvConfig) -> Simulator:
    """The env's simulator; refuses action ranges whose strongest stroke would load the part
    beyond the contact table (checked once here, so steps never need to)."""
    sim = simulator(cfg.preset, shape=cfg.shape, wavelength=cfg.wavelength,
                    kinematics=cfg.kinematics, mode=cfg.mode, dt=cfg.dt, max_time=cfg.max_time,
                    min_steps=cfg.min_steps, max_steps=cfg.max_steps)
    f, h = np.array([cfg.freq_range[1]]), np.array([cfg.stroke_range[1]])
    try:
        sim.check_firings(f, h)
    except TableRangeError as exc:
        raise ParameterError(f"EnvConfig.freq_range / stroke_range: {exc}") from None
    heaviest = cfg.mass_factor_range[1]
    if heaviest > 1.0:
        try:
            sim.check_firings(f, h, mass_factor=heaviest)
        except TableRangeError as exc:
            raise ParameterError(f"EnvConfig.mass_factor_range = {cfg.mass_factor_range!r} is "
                                 f"invalid with these freq_range / stroke_range: a part "
                                 f"{heaviest:g} times heavier: {exc}; lower the upper factor"
                                 ) from None
    return sim


def check_target(target) -> float:
    """A target from ``reset(options=...)`` [m]: finite and where the observation can show it."""
    limit = task.OBS_BOUND * task.LENGTH_SCALE
    numeric = isinstance(target, (numbers.Real, np.floating, np.integer)) and not isinstance(
        target, (bool, np.bool_))
    t = float(target) if numeric else math.nan
    if not (np.isfinite(t) and abs(t) <= limit):
        raise ValueError(f"options['target'] = {target!r} is invalid: must be a finite distance "
                         f"beyond actuator 1 within +-{limit:g} m")
    return t


def check_render_mode(render_mode, supported) -> None:
    if render_mode is not None and render_mode not in supported:
        raise ValueError(f"render_mode {render_mode!r} not supported; use None or one of "
                         f"{list(supported)} (for a window, wrap an rgb_array env in "
                         "gymnasium.wrappers.HumanRendering)")


def raise_if_beyond_table(outcome: str, sim: Simulator) -> None:
    if outcome == "load_beyond_table":
        raise TableRangeError(f"the normal load left the contact table ({sim.table.max_load:.3g} "
                              "N) during a stroke; rebuild the table with a larger load_ratio")


class MicroConveyorEnv(gym.Env):
    """Goal-conditioned micropart conveyor (physics: Kogut–Etsion contact, stick–slip dynamics).

    A part starts ``start_offset`` upstream of actuator 1 (at x = 0) of a linear array of
    ``n_actuators`` actuators ``spacing`` apart and must come to rest within ``tolerance`` of a
    target downstream (+x). Each ``step`` fires the **next** actuator with the action's frequency,
    stroke and delay: the part coasts during the delay, the stroke runs, and the step returns when
    the stroke ends; the last step also runs the part to rest. With ``stop_at_target`` (default
    on) the conveyor stops as soon as the part is delivered: if after a stroke the part, left
    alone, would come to rest within ``tolerance`` of the target, it does and the episode ends.
    An episode therefore has at most ``n_actuators`` steps.

    ## Action space: ``Box(-1, 1, (3,), float32)``

    | index | meaning | mapping |
    |---|---|---|
    | 0 | stroke frequency f [Hz] (the stroke lasts 1/f) | log-uniform onto ``freq_range`` (200–10000 Hz) |
    | 1 | stroke height h [m] | linear onto ``stroke_range`` (100–200 µm) |
    | 2 | delay before the stroke [s] | linear onto ``delay_range`` (0–0.1 s) |

    Out-of-range actions are **clipped** to [-1, 1]; NaN or inf, a shape other than ``(3,)`` or a
    non-numeric dtype raise ``ValueError``.

    ## Observation space: ``Box(-10, 10, (6,), float32)`` (values clipped to the bounds)

    | index | observation | scaling |
    |---|---|---|
    | 0 | position error x − target | / 10 mm |
    | 1 | velocity dx/dt | / 0.5 m/s |
    | 2 | distance from the part to the next actuator (0 once all fired) | / spacing |
    | 3 | elapsed simulated time | / max_time |
    | 4 | fraction of actuators fired | – |
    | 5 | target (distance beyond actuator 1) | / 10 mm |

    ## Reward
    ``Phi(s') - Phi(s) - time_cost * (t' - t) + success_bonus * [success]`` with the potential
    ``Phi = -min(|x - target|, progress_horizon) / progress_scale`` (the horizon: default twice the
    farthest start-to-target distance). On detachment the part forfeits all progress (it takes
    the potential of the horizon), pays the time
    cost up to ``max_time`` and ``detach_penalty``: any episode ending at rest returns more than
    any detaching one, and at equal time a closer rest returns more (:mod:`.task`).

    ## Episode end
    ``terminated``: at rest after the last firing, delivered (``stop_at_target``: at rest within
    tolerance after any firing), or detachment. ``truncated``: the simulated
    time limit ``max_time`` (or an unresolved stick–slip chatter, reported in ``info["outcome"]``).
    ``info``: ``is_success``, ``position_error_m`` (signed x − target, now), ``outcome``
    (``moving``/``rest``/``detached``/``max_time``/``too_many_events``), ``sim_time_s``,
    ``frequency_hz``, ``stroke_m``, ``delay_s`` (the decoded action as fired, execution noise
    included); with randomisation on also ``friction_factor`` and ``mass_factor`` (this episode's).

    ## Per-episode randomisation (off by default; docs/randomisation.md)

    | field | unit | default | valid | drawn | effect |
    |---|---|---|---|---|---|
    | ``action_noise`` | action units | 0.0 (off) | [0, 1] | per firing (at reset, for the episode) | fires ``clip(action + σ z)``, z ~ N(0, 1) per component |
    | ``friction_factor_range`` | – | (1, 1) | [0.1, 10], low ≤ high | uniform per episode | multiplies the friction Q(N), static and sliding |
    | ``mass_factor_range`` | – | (1, 1) | [0.1, 10], low ≤ high | uniform per episode | multiplies the part mass: inertia and weight |

    The contact table does not depend on the mass (only the load it is read at), so it serves every
    factor; the heaviest part's peak load must stay inside it (checked at construction). Draws
    come from streams derived from the env's seeded generator, never from it: off, nothing is
    drawn (rollouts unchanged); on, starts and targets are those of the env without, and a part
    seeded ``s`` draws the same in the single env and in the batched env.

    ## Arguments
    Any field of :class:`EnvConfig` (defaults in ``configs/envs/MicroConveyor-v0.yaml``), e.g.
    ``gym.make("MicroConveyor-v0", n_actuators=3, tolerance=100e-6)``; ``render_mode`` ``"rgb_array"``
    (for a window, wrap with ``gymnasium.wrappers.HumanRendering``, which needs pygame).
    ``reset(options={"target": d})`` sets the target distance d [m] beyond actuator 1.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}

    def __init__(self, render_mode: str | None = None, config: EnvConfig | None = None, **kwargs):
        if config is not None and kwargs:
            raise ValueError("give either config= or keyword overrides, not both")
        if config is not None and not isinstance(config, EnvConfig):
            raise ValueError(f"config must be an EnvConfig, got {type(config).__name__}")
        self.config = config or EnvConfig.from_yaml(**kwargs)
        check_render_mode(render_mode, self.metadata["render_modes"])
        self.render_mode = render_mode
        self.sim = make_simulator(self.config)
        self.positions = np.asarray(self.config.actuator_positions, dtype=np.float64)
        self.action_space = spaces.Box(-1.0, 1.0, (actions.ACTION_DIM,), np.float32)
        self.observation_space = spaces.Box(-task.OBS_BOUND, task.OBS_BOUND, (task.OBS_DIM,),
                                            np.float32)
        self._AC, self._TC = actions.constants(self.config), task.constants(self.config)
        self._kout = np.zeros((1, kernel.N_OUT))
        self._res = np.zeros((1, kstep.N_S))
        self._obs_buf = np.zeros((1, task.OBS_DIM), dtype=np.float32)
        self._active = np.ones(1, dtype=np.bool_)
        self._x, self._v, self._t = np.zeros(1), np.zeros(1), np.zeros(1)
        self._fired = np.zeros(1, dtype=np.int64)
        self._target = np.full(1, np.nan)
        self._done = True
        self._last_firing = None
        # per-episode randomisation (randomisation.py): the part's constants row, its noise, the
        # factors drawn, and the streams derived from np_random (re-derived when it is replaced)
        self._P = self.sim.params.reshape(1, -1).copy()
        self._noise = (np.zeros((1, self.config.n_actuators, 3)) if self.config.action_noise > 0
                       else kstep.NO_NOISE)
        self._factors = (1.0, 1.0)
        self._rand_streams: tuple | None = None
        self._rand_src = None
        self._randomised = self.config.randomised

    # state accessors (SI units)
    x = property(lambda self: float(self._x[0]), doc="part position [m]")
    v = property(lambda self: float(self._v[0]), doc="part velocity [m/s]")
    t = property(lambda self: float(self._t[0]), doc="simulated time [s]")
    fired = property(lambda self: int(self._fired[0]), doc="actuators fired so far")
    target = property(lambda self: float(self._target[0]), doc="target position [m]")
    friction_factor = property(lambda self: self._factors[0],
                               doc="this episode's factor on the friction [-]")
    mass_factor = property(lambda self: self._factors[1], doc="this episode's factor on the mass [-]")

    # ------------------------------------------------------------------ API
    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        given = check_target(options["target"]) if options and "target" in options else None
        x0, target = task.initial_state(self.config, self.np_random, given)
        if self._randomised:
            if self._rand_src is not self.np_random:  # seeded anew (or replaced): new streams
                self._rand_streams = randomisation.streams(self.np_random)
                self._rand_src = self.np_random
            assert self._rand_streams is not None
            self._factors = randomisation.draw(self.config, self._rand_streams, self.sim.params,
                                               self._P[0], self._noise[0] if self._noise.size
                                               else None)
        self._x[0], self._v[0], self._t[0] = x0, 0.0, 0.0
        self._fired[0] = 0
        self._target[0] = target
        self._done = False
        self._last_firing = None
        kstep.observe_all(self._x, self._v, self._t, self._fired, self._target, self._TC,
                          self.positions, self._obs_buf)
        return self._obs_buf[0].copy(), self._info("moving", False)

    def step(self, action):
        if self._done:
            raise RuntimeError("step() called on a finished episode: call reset() first")
        a = actions.check_actions(action, None)
        xa = float(self.positions[self.fired])
        kstep.step_serial(a, self._noise, self._x, self._v, self._t, self._fired, self._target,
                          self._active, self._AC, self._TC, self.sim.dt, self.sim.min_steps,
                          self.positions, self._P, *self.sim.tables, kstep.NO_RECORD,
                          self._kout, self._res, self._obs_buf)
        res = self._res[0]
        outcome = kernel.OUTCOMES[int(res[kstep.S_OUTCOME])]
        raise_if_beyond_table(outcome, self.sim)
        terminated = outcome in ("rest", "detached")
        truncated = outcome in ("max_time", "too_many_events")
        self._done = terminated or truncated
        f, h, d = float(res[kstep.S_F]), float(res[kstep.S_H]), float(res[kstep.S_D])
        self._last_firing = (xa, f, h, d)
        info = self._info(outcome, bool(res[kstep.S_SUCCESS]))
        info["frequency_hz"], info["stroke_m"], info["delay_s"] = f, h, d
        return (self._obs_buf[0].copy(), float(res[kstep.S_REWARD]), terminated, truncated, info)

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        from .render import render_frame

        return render_frame(self.config, self.x, self.target, self.fired, self._last_firing,
                            self.t)

    # ------------------------------------------------------------------ helpers
    def _info(self, outcome: str, success: bool) -> dict:
        info = {"is_success": success, "position_error_m": float(self.x - self.target),
                "outcome": outcome, "sim_time_s": float(self.t)}
        if self._randomised:
            info["friction_factor"], info["mass_factor"] = self._factors
        return info
