"""MicroPositioner-v0's single env: place a micropart anywhere along a long actuator array,
firing any actuator, one firing at a time."""
from __future__ import annotations

from typing import Any, cast

from gymnasium.core import RenderFrame

from ..core.single import SingleEnv
from ..rail.parts import OwnsRail
from .config import PositionerConfig
from .part_state import PositionerState
from .state import PositionerParts


class MicroPositionerEnv(OwnsRail, SingleEnv):
    """Closed-loop positioning of a micropart on a long linear actuator array (physics:
    Kogut–Etsion contact, stick–slip dynamics, chapter 4's surface as MicroConveyor-v1).

    ``n_actuators`` actuators ``spacing`` apart (default 43, 0.25 mm: 0–10.5 mm) lie under the
    whole target range. The part starts ``start_offset`` upstream of actuator 1 and must come
    to rest within ``tolerance`` of a target drawn from ``target_range`` (0.5–10 mm). Each
    ``step`` is one firing of **any** actuator, chosen by the action, with the action's
    frequency and stroke; the step returns once the part is at rest again, as a camera would
    see it. A resting part moves towards and past the actuator that fires, so the controller
    carries the part forward by firing ahead of it and back by firing behind it, and can correct
    every firing's error with the next.

    ## Action space: ``Box(-1, 1, (3,), float32)``

    | index | meaning | mapping |
    |---|---|---|
    | 0 | aim: which actuator fires | the actuator nearest ``x + a0 * pick_reach`` (±0.5 mm) fires |
    | 1 | stroke frequency f [Hz] (the stroke lasts 1/f) | log-uniform onto ``freq_range`` (200–2000 Hz) |
    | 2 | stroke height h [m] | linear onto ``stroke_range`` (100–200 µm) |

    Out-of-range actions are **clipped** to [-1, 1]; NaN or inf, a shape other than ``(3,)`` or a
    non-numeric dtype raise ``ValueError``.

    ## Observation space: ``Box(-10, 10, (12,), float32)`` (values clipped to the bounds)

    | index | observation | scaling |
    |---|---|---|
    | 0 | position error x − target | / 2 mm |
    | 1 | position error, log scale: sign(e) ln(1 + abs(e) / 10 µm) | – (1.8 at 50 µm, 4.6 at 1 mm) |
    | 2 | nearest actuator's position − x | / spacing |
    | 3 | the last firing's displacement | / 1 mm |
    | 4 | the last firing's frequency as commanded | action units |
    | 5 | the last firing's stroke as commanded | action units |
    | 6 | the last fired actuator − the part's position before it | / spacing |
    | 7 | 1 once a firing was made, else 0 | – |
    | 8 | fraction of ``max_firings`` used | – |
    | 9 | elapsed simulated time | / max_time |
    | 10 | target | / 10 mm |
    | 11 | position x | / 10 mm |

    Entry 1 resolves the last tens of micrometres as well as the millimetres (a linear scale
    that shows 10 mm shows 50 µm as 0.5 % of its range, and observation normalisation would
    shrink it further). The part is at rest between steps, so there is no velocity. Entries 3–7 are the last
    firing as commanded with what it did (execution noise is not in them: a controller cannot
    know it): one observed transition of the dynamics, from which a controller can tell this
    episode's friction and mass (hidden, with randomisation on) without a memory of its own.

    ## Reward
    ``Phi(s') - Phi(s) - time_cost * (t' - t) + success_bonus * [success]`` with
    ``Phi = -min(|x - target|, progress_horizon) / progress_scale``; on detachment the part
    forfeits all progress, pays the time cost up to ``max_time`` and ``detach_penalty``: as
    MicroConveyor-v1 (:mod:`..line.task` says why this ranks episodes as it should).

    ## Episode end
    ``terminated``: the part rests within ``tolerance`` of the target (success), the
    ``max_firings``-th firing is spent, or the part detaches. ``truncated``: the simulated time
    limit ``max_time`` (or unresolved stick–slip chatter). ``info``: ``is_success``,
    ``position_error_m`` (signed x − target), ``outcome`` (``moving`` while the episode goes on,
    ``rest`` at its end at rest, ``detached``, ``max_time``, ``too_many_events``),
    ``sim_time_s``, ``actuator`` (index of the actuator fired), ``frequency_hz``, ``stroke_m``
    (as fired, execution noise included); with randomisation on also ``friction_factor`` and
    ``mass_factor``.

    ## Per-episode randomisation (off by default; docs/randomisation.md)
    As MicroConveyor-v1: ``action_noise`` σ [action units] on the frequency and stroke of every
    firing (not on the aim: which actuator fires is a switch), ``friction_factor_range`` and
    ``mass_factor_range`` [-] uniform per episode; the draws come from streams derived from the
    env's seeded generator, and the single env seeded ``s + i`` draws what sub-env ``i`` of the
    batched env seeded ``s`` draws.

    ## Arguments
    Any field of :class:`~.config.PositionerConfig` (defaults in
    ``configs/envs/MicroPositioner-v0.yaml``), e.g. ``gym.make("MicroPositioner-v0",
    action_noise=3e-3, friction_factor_range=(0.95, 1.05))``. ``reset(options={"target": d})``
    sets the target d [m]; ``reset(options={"state": s})`` continues from a saved
    :class:`~.part_state.PositionerState` (:meth:`get_state`) exactly, observations included.
    ``render_mode="rgb_array"``: the array, the part, the target and the last stroke's peak.

    ## Version history
    * **v0** (package 0.3.0): the scene as described; the array's spacing and length were chosen
      by measuring which spacing lets a model-based controller hold every target
      (docs/env.md, "MicroPositioner-v0's array").
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}

    config_class = PositionerConfig
    conveyor_class = PositionerParts
    config: PositionerConfig
    conveyor: PositionerParts
    _last_firing: tuple[float, float, float, float] | None

    # state accessors (SI units)
    x = property(lambda self: float(self.conveyor.parts.x[0]), doc="part position [m]")
    t = property(lambda self: float(self.conveyor.parts.t[0]), doc="simulated time [s]")
    fired = property(lambda self: int(self.conveyor.parts.fired[0]), doc="firings so far")
    target = property(lambda self: float(self.conveyor.parts.target[0]), doc="target [m]")
    friction_factor = property(lambda self: float(self.conveyor.friction_factor[0]),
                               doc="this episode's factor on the friction [-]")
    mass_factor = property(lambda self: float(self.conveyor.mass_factor[0]),
                           doc="this episode's factor on the mass [-]")

    def get_state(self) -> PositionerState:
        """The part's :class:`~.part_state.PositionerState` now (SI units)."""
        return cast(PositionerState, super().get_state())

    def _after_step(self, info: dict[str, Any]) -> None:
        self._last_firing = (float(self.positions[info["actuator"]]), info["frequency_hz"],
                             info["stroke_m"], 0.0)

    def render(self) -> RenderFrame | list[RenderFrame] | None:
        """``rgb_array``: the frame of the state now (the array, the part at rest, the target
        and its tolerance, the last stroke's peak deformation dashed)."""
        if self.render_mode != "rgb_array":
            return None
        from ..rail.render import render_frame

        return render_frame(self.config, self.x, self.target, 0, self._last_firing, self.t)
