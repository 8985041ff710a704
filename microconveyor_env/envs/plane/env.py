"""MicroConveyor2D-v0 and -v1: position a micropart in a plane with a grid of micro-actuators (v1:
under per-episode randomisation)."""
from __future__ import annotations

from typing import Any, cast

from gymnasium.core import RenderFrame

from ..core.single import SingleEnv
from .config import PlaneEnvConfig
from .part_state import PlaneState
from .state import PlaneConveyor


class MicroConveyor2DEnv(SingleEnv):
    """Goal-conditioned micropart positioning on a surface (docs/physics.md §10: the 1-D model's
    Kogut–Etsion contact and stick–slip dynamics on a plane deformed by radial bumps).

    A part starts at ``start`` (default the centre of the grid) on a level surface over an
    ``nx`` x ``ny`` grid of actuators ``spacing`` apart (actuator (i, j), index ``i + nx j``, at
    ``(i, j) * spacing``) and must come to rest within ``tolerance`` (a disc, Euclidean) of a
    target drawn uniformly on the grid's box. Each ``step`` fires **one actuator the agent picks
    near the part**, with the action's frequency, stroke and delay: the part coasts during the
    delay, the bump rises and falls under it, and the step returns when the stroke ends; the
    ``max_firings``-th step also runs the part to rest. With ``stop_at_target`` (default on) the
    episode ends as soon as the part, left alone, would come to rest within tolerance.

    ## Action space: ``Box(-1, 1, (5,), float32)``

    | index | meaning | mapping |
    |---|---|---|
    | 0, 1 | aim offset from the part (x, y) [m] | times ``pick_reach`` (0.5 mm): the actuator nearest to part + offset fires |
    | 2 | stroke frequency f [Hz] | log-uniform onto ``freq_range`` (200–2000 Hz) |
    | 3 | stroke height h [m] | linear onto ``stroke_range`` (100–200 µm) |
    | 4 | delay before the stroke [s] | linear onto ``delay_range`` (0–0.1 s) |

    Components 2–4 decode exactly as MicroConveyor-v1's action (:func:`..core.actions.decode`).
    Out-of-range actions are **clipped** to [-1, 1]; NaN or inf, a shape other than ``(5,)`` or a
    non-numeric dtype raise ``ValueError``.

    *Why an aim offset.* A firing moves the part along the line through it and the fired
    actuator (the bump pulls or pushes it radially), so the actuator's position relative to the
    part is the direction of the move: the agent chooses it as a continuous offset, and the
    actuator nearest to the aimed point fires (ties to the lower index; off the grid, the nearest
    edge actuator). With a reach of one pitch the aim point covers the part's cell and its
    neighbours, so the choice is always among the actuators whose bump reaches the part (a
    firing farther than ~WL/2 does nothing), whatever the grid's size; a continuous Box suits
    PPO and SAC alike (a discrete choice of 25 actuators would not fit SAC, and most of the 25
    would be out of reach). A direction-only action (an angle) would fire the same few
    neighbours but cannot choose the actuator under the part.

    ## Observation space: ``Box(-10, 10, (10,), float32)`` (values clipped to the bounds)

    | index | observation | scaling |
    |---|---|---|
    | 0, 1 | position error p − target (x, y) | / 1 mm |
    | 2, 3 | velocity (vx, vy) | / 0.1 m/s |
    | 4, 5 | part − nearest actuator (x, y) (where the part sits in its cell) | / spacing |
    | 6 | elapsed simulated time | / max_time |
    | 7 | fraction of the firings used | / max_firings |
    | 8, 9 | target − grid centre (x, y) | / 1 mm |

    ## Reward
    ``Phi(s') - Phi(s) - time_cost * (t' - t) + success_bonus * [success]`` with
    ``Phi = -min(|p - target|, progress_horizon) / progress_scale`` (Euclidean; horizon default:
    twice the farthest start-to-target distance). On detachment the part forfeits all progress,
    pays the time cost up to ``max_time`` and ``detach_penalty``: any episode ending at rest
    returns more than any detaching one, and at equal time a closer rest returns more
    (:mod:`.task`; hypothesis properties in tests/envs/test_plane_env_reward.py).

    ## Episode end
    ``terminated``: at rest after the ``max_firings``-th firing (default 8), delivered
    (``stop_at_target``: at rest within tolerance after any firing), or detachment.
    ``truncated``: the simulated time limit ``max_time`` (or an unresolved stick–slip chatter).
    ``info``: ``is_success``, ``position_error_m`` ((x, y) of p − target, a tuple), ``distance_m``
    (Euclidean), ``outcome``, ``sim_time_s``, and after a step ``actuator`` (the index fired),
    ``frequency_hz``, ``stroke_m``, ``delay_s`` (as fired, execution noise included); with
    randomisation on also ``friction_factor`` and ``mass_factor`` (this episode's).

    ## Per-episode randomisation (off in v0, on in v1; docs/randomisation.md)

    | field | unit | v0 (off) | v1 | allowed | drawn | effect |
    |---|---|---|---|---|---|---|
    | ``action_noise`` | action units | 0.0 | 3e-3 | [0, 1] | per firing (at reset, for the episode) | fires ``clip(a + σ z)`` for the frequency, stroke and delay components, z ~ N(0, 1) each; the aim is exact |
    | ``friction_factor_range`` | – | (1, 1) | (0.95, 1.05) | [0.1, 10], low ≤ high | uniform per episode | multiplies the friction Q(N), static and sliding |
    | ``mass_factor_range`` | – | (1, 1) | (0.95, 1.05) | [0.1, 10], low ≤ high | uniform per episode | multiplies the part mass: inertia and weight |

    The draws come from streams derived from the part's generator (:mod:`..core.randomisation`,
    the line's too): off, nothing is drawn and the episodes are v0's bit for bit; a seed gives its
    factors and noise; sub-env ``i`` of the batched env seeded ``s`` draws what a single env seeded
    ``s + i`` draws; levels with one seed share their random numbers, scaled. The heaviest part's
    peak load must stay inside the contact table (checked at construction). :meth:`get_state`
    carries the factors and the noise.

    ## Scene (``configs/envs/MicroConveyor2D-v0.yaml``; any field of :class:`PlaneEnvConfig`)
    5 x 5 actuators 0.5 mm apart (a 2 x 2 mm grid at the 1-D pitch) on
    MicroConveyor-v1's surface (preset ``conveyor``, chapter 4), Gaussian bumps of wavelength
    **2 mm** (width WL/6 = 0.33 mm) and frequencies up to **2000 Hz**. Why
    (``scripts/plane_scene_scan.py``: 400 random firings as the env picks them, from a part at
    rest at typical points of a cell): a bump moves a part only within about one width of its
    centre, and on the plane a part can come to rest anywhere, including a cell's centre, 0.35 mm
    from its four actuators. With v1's 0.6 mm wavelength and a 0.5 mm pitch no firing moved a part
    resting at a cell's centre, at an edge's middle or on an actuator by more than 25 µm (0.35 mm
    pitch: 1 % from a cell's centre, none from on an actuator): such a part could never be moved
    again. With 2 mm every point can be moved (52 % of the firings from a cell's centre, 36 % from
    an edge's middle, 18 % from on an actuator), by 0.1–0.16 mm (median) up to 1.1 mm, so a part
    stays on the grid and a target (1.4 mm away at most) takes a few firings. A 1 mm wavelength
    on a 0.25 mm pitch works too but carries parts up to 3.7 mm, off a 1 mm grid. Above ~1.3 kHz
    strokes of 200 µm detach the part (as in 1-D): 2 kHz keeps detachment reachable (the agent
    must learn to avoid it: ~30 % of random firings detach) without making most of the action
    box detach (10 kHz, v1's limit, would).
    ``max_firings`` 8: a few moves, plus corrections.

    ## Arguments
    Any field of :class:`PlaneEnvConfig` (SI units), e.g. ``gym.make("MicroConveyor2D-v0",
    nx=7, ny=7, tolerance=100e-6)``, or ``config=PlaneEnvConfig(...)``.
    ``reset(options={"target": (x, y)})`` sets the target [m] (actuator 0 at the origin).
    ``reset(options={"state": s})`` starts from a saved part state ``s`` (:meth:`get_state`, a
    :class:`~.part_state.PlaneState` or its dict): the episode continues exactly as the one it
    was saved in; a state of another scene or id, or a value out of bounds, is refused before
    anything changes (:mod:`.part_state`).
    ``spec.max_episode_steps`` is 1000, an upper bound that never cuts an episode short.

    ## Rendering
    ``render_mode="rgb_array"``: ``render()`` returns a 480 x 400 top view: the grid, the height
    map and contours of the last firing's bump at its peak, the part's path (its position after
    the reset and each step), the part, the target and its tolerance disc. Never changes a step.

    ## Version history
    * **v1** (package 0.2.0): v0's scene under per-episode randomisation by default
      (``configs/envs/MicroConveyor2D-v1.yaml``: execution noise 3e-3, friction and mass factors
      in [0.95, 1.05]) and 12 firings in 1.5 s (v0: 8 in 1 s): under that noise v0's PPO placed
      75-78 % of 1,000 targets within 50 µm with 8 firings and 81-83 % with 12, 16 adding
      nothing (docs/env.md, "MicroConveyor2D-v1"). Task, spaces and reward as v0's.
    * **v0** (package 0.2.0): the first 2-D version; the randomisation fields exist, off. No
      observation history (the 1-D v1 has it).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}

    config_class = PlaneEnvConfig
    conveyor_class = PlaneConveyor
    config: PlaneEnvConfig
    conveyor: PlaneConveyor
    _last_firing: tuple[int, float, float, float] | None

    def __init__(self, render_mode: str | None = None, config: PlaneEnvConfig | None = None,
                 **kwargs: Any) -> None:
        super().__init__(render_mode, config, **kwargs)
        self._path: list[tuple[float, float]] = []

    # state accessors (SI units)
    x = property(lambda self: float(self.conveyor.parts.x[0]), doc="part x [m]")
    y = property(lambda self: float(self.conveyor.parts.y[0]), doc="part y [m]")
    vx = property(lambda self: float(self.conveyor.parts.vx[0]), doc="part vx [m/s]")
    vy = property(lambda self: float(self.conveyor.parts.vy[0]), doc="part vy [m/s]")
    t = property(lambda self: float(self.conveyor.parts.t[0]), doc="simulated time [s]")
    fired = property(lambda self: int(self.conveyor.parts.fired[0]), doc="firings so far")
    target = property(lambda self: (float(self.conveyor.parts.tx[0]),
                                    float(self.conveyor.parts.ty[0])), doc="target (x, y) [m]")
    positions = property(lambda self: self.conveyor.positions,
                         doc="actuator positions (n_actuators, 2) [m]")
    path = property(lambda self: tuple(self._path),
                    doc="the part's positions [m] after the reset and each step")
    friction_factor = property(lambda self: float(self.conveyor.friction_factor[0]),
                               doc="this episode's factor on the friction [-]")
    mass_factor = property(lambda self: float(self.conveyor.mass_factor[0]),
                           doc="this episode's factor on the mass [-]")

    def _after_reset(self) -> None:
        self._path = [(self.x, self.y)]

    def get_state(self) -> PlaneState:
        """The part's :class:`~.part_state.PlaneState` now (SI units): ``reset(options=
        {"state": s})`` continues the episode from it exactly."""
        return cast(PlaneState, super().get_state())

    def _after_step(self, info: dict[str, Any]) -> None:
        self._last_firing = (info["actuator"], info["frequency_hz"], info["stroke_m"],
                             info["delay_s"])
        self._path.append((self.x, self.y))

    def render(self) -> RenderFrame | list[RenderFrame] | None:
        """``rgb_array``: the frame of the state now (uint8 (400, 480, 3))."""
        if self.render_mode != "rgb_array":
            return None
        from .render import render_plane_frame

        if not self._path:
            raise RuntimeError("render() before the first reset(): there is no part to draw")
        return render_plane_frame(self.config, self._path, self.target, self.fired,
                                  self._last_firing, self.t)
