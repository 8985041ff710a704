"""The line's single env, MicroConveyor-v0 / -v1: carry a micropart to a target with a linear
array of micro-actuators."""
from __future__ import annotations

from typing import Any, cast

import numpy as np
from gymnasium.core import RenderFrame

from ..core.single import SingleEnv
from ..core.window import installed_modes
from ..rail.parts import OwnsRail
from .config import EnvConfig
from .frames import EnvRenderer, check_frames_per_stroke
from .part_state import PartState
from .state import Conveyor


class MicroConveyorEnv(OwnsRail, SingleEnv):
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

    ## Observation history (``observe_history`` k, off by default)
    With k > 0 [firings, integer in [0, ``n_actuators`` − 1]] the observation is
    ``Box(-10, 10, (6 + 10 k,), float32)``: the row above, then the k most recent firings of this
    episode, the latest first, 10 numbers each: the 6-number row observed **before** that firing,
    the action **as commanded** (3 numbers, action units, clipped to [-1, 1]; the execution
    noise is not in it: the controller cannot know it) and 1.0 (the slot holds a firing; an empty
    slot, before k firings, is all zeros). Why this: with randomisation the friction and mass
    factors are hidden, but each remembered (row before, action) pair with the row after it (the
    next slot's row, or the current one) is one observed transition of the dynamics: the velocity
    and position a known firing left from a known state tell this episode's friction and mass,
    which the current row alone cannot (it holds no action). Actions, not the fired (noisy)
    values, because only what was commanded is known to a real controller. k = ``n_actuators``
    − 1 remembers the whole episode at the last decision. ``reset`` empties the history, and so
    does ``reset(options={"state": s})``: a :class:`~.part_state.PartState` carries no history,
    so an episode restarted from a saved state starts with empty slots (its rows and dynamics
    continue exactly). ``observe_history`` = 0 is the 6-number observation, unchanged bit for
    bit. The single and the batched env fill the history identically.

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
    Any field of :class:`EnvConfig` (defaults in ``configs/envs/MicroConveyor-v0.yaml``; v1's
    changes in ``configs/envs/MicroConveyor-v1.yaml``, its ``gym.spec`` kwargs), e.g.
    ``gym.make("MicroConveyor-v1", n_actuators=3, tolerance=100e-6)``.
    ``reset(options={"target": d})`` sets the target distance d [m] beyond actuator 1;
    ``reset(options={"state": s})`` starts from a saved part state ``s`` (:meth:`get_state`, a
    :class:`~.part_state.PartState` or its dict): the episode continues exactly as the one it was
    saved from (model-predictive control plans from it), with an empty observation history.

    ## Rendering (never changes a step: tests/envs/test_render.py)
    ``render_mode``: ``"rgb_array"`` (``render()`` gives the frame of the state now),
    ``"rgb_array_list"`` (the frames since the last ``render()`` or ``reset()``) or ``"human"``
    (a pygame window showing them at ``metadata["render_fps"]``; the ``render`` extra).
    ``render_frames_per_stroke`` (default 1: one frame per reset and per step, the state after
    it) n > 1, with ``rgb_array_list`` or ``human``: up to n frames of each phase of a firing
    (the slide through the delay, the stroke, the slide to rest), the part on the surface as it
    deforms, picked from the firing's real trajectory (:mod:`.frames`), and ``render_fps`` =
    4 n. Gymnasium's ``RecordVideo`` keeps only the last frame of each list;
    :class:`~..core.video.RecordStrokeVideo` keeps them all.
    ``spec.max_episode_steps`` (v1) is 1000, the most actuators a config allows: an upper bound
    that never cuts an episode short, whatever ``n_actuators`` is (an episode ends by itself
    after at most ``n_actuators`` steps).

    ## Version history
    * **v1** (package 0.2.0): the same task on the dissertation's **chapter-4 surface** (preset
      ``conveyor``, Table 4.2: surface energy 0.5 J/m², against 1 J/m² in v0): pull-off
      2.53 µN instead of 6.2 µN, friction at the weight 17.5 nN instead of 80 nN, so a sliding
      part decelerates at 8.8 m/s² instead of 40 m/s² and travels ~4.5x further per firing.
      The target range and the scene (actuators, spacing) were chosen by measuring which
      targets an open-loop plan reaches and holds under action noise (docs/env.md, "v1's scene
      and target range"). ``spec.max_episode_steps`` is set. v0's conveyor task ran on chapter
      3's single-actuator surface, which cannot carry a part past ~5 mm, where the
      dissertation's conveyor carries it 10 mm.
    * **v0** (package 0.1.0): the goal-conditioned conveyor on the chapter-3 surface (preset
      ``feasibility``), 5 actuators 0.5 mm apart, targets 0.5–3 mm. Unchanged and still
      registered: its stored rollouts and shipped policies reproduce.
    """

    metadata = {"render_modes": ["rgb_array", "rgb_array_list", "human"], "render_fps": 4}

    config_class = EnvConfig
    conveyor_class = Conveyor
    config: EnvConfig
    conveyor: Conveyor
    _last_firing: tuple[float, float, float, float] | None

    def __init__(self, render_mode: str | None = None, config: EnvConfig | None = None,
                 render_frames_per_stroke: int = 1, **kwargs: Any) -> None:
        super().__init__(render_mode, config, **kwargs)
        n_frames = check_frames_per_stroke(render_frames_per_stroke, render_mode)
        self.render_frames_per_stroke = n_frames
        # the modes this install renders (human: with pygame; core/window.py)
        self.metadata = {**self.metadata,
                         "render_modes": installed_modes(self.metadata["render_modes"])}
        if n_frames > 1:  # each phase of a firing (n frames) lasts 1/4 s, as a firing at n = 1
            self.metadata = {**self.metadata, "render_fps": 4 * n_frames}
        self._renderer = EnvRenderer(self, render_mode, n_frames)

    # state accessors (SI units)
    x = property(lambda self: float(self.conveyor.parts.x[0]), doc="part position [m]")
    v = property(lambda self: float(self.conveyor.parts.v[0]), doc="part velocity [m/s]")
    t = property(lambda self: float(self.conveyor.parts.t[0]), doc="simulated time [s]")
    fired = property(lambda self: int(self.conveyor.parts.fired[0]), doc="actuators fired so far")
    target = property(lambda self: float(self.conveyor.parts.target[0]), doc="target position [m]")
    friction_factor = property(lambda self: float(self.conveyor.friction_factor[0]),
                               doc="this episode's factor on the friction [-]")
    mass_factor = property(lambda self: float(self.conveyor.mass_factor[0]),
                           doc="this episode's factor on the mass [-]")

    # ------------------------------------------------------------------ API
    def _after_reset(self) -> None:
        self._renderer.reset()
        if self.render_mode == "human":
            self.render()

    def get_state(self) -> PartState:
        """The part's :class:`~.part_state.PartState` now (SI units): ``reset(options=
        {"state": s})`` continues the episode from it exactly; an env of another scene refuses
        it."""
        return cast(PartState, super().get_state())

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        k = self.fired
        # the state before the firing, kept only to draw it (rgb_array_list, human)
        before = (self.x, self.v, self.t) if self._renderer.collecting else None
        result = super().step(action)
        info = result[4]
        f, h, d = info["frequency_hz"], info["stroke_m"], info["delay_s"]
        self._last_firing = (float(self.positions[k]), f, h, d)
        if before is not None:  # the frames of this firing: after the step, never changing it
            self._renderer.fired(k, before, f, h, d, info["outcome"])
            if self.render_mode == "human":
                self.render()
        return result

    def render(self) -> RenderFrame | list[RenderFrame] | None:
        """``rgb_array``: the frame of the state now; ``rgb_array_list``: the frames since the
        last ``render()`` or ``reset()``; ``human``: shows those in the window (called by
        ``reset`` and ``step``), returns None."""
        if self.render_mode == "rgb_array":
            from ..rail.render import render_frame

            return render_frame(self.config, self.x, self.target, self.fired, self._last_firing,
                                self.t)
        if self.render_mode == "rgb_array_list":
            frames: list[RenderFrame] = list(self._renderer.frames())
            return frames
        if self.render_mode == "human":
            self._renderer.show(self.metadata["render_fps"])
        return None

    def close(self) -> None:
        self._renderer.close()
        super().close()
