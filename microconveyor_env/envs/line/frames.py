"""Frames during a firing (``render_frames_per_stroke`` > 1): which states of the simulation a
video shows, picked from the firing's real trajectory (:mod:`...physics.trajectory`).

An env step is one firing: the part slides through the delay (the slide that follows the
previous stroke), the stroke runs, and, when the episode ends at rest, the part slides to rest.
Each of these phases in which something moves gets up to ``n`` frames at evenly spaced times of
the phase (the slide: of its moving part); each frame is the simulator's own state at the last
recorded row at or before that time (the RK4 steps and events of the stroke, the exact
closed-form coast), never an interpolation between rows. So a 0.1 ms stroke and a 20 ms slide
get the same number of frames: a video is evenly paced per phase, not in simulated time; every
frame's title gives its simulated time. A phase with fewer recorded rows than ``n`` gets one
frame per row. The surface is drawn as it is at the frame's time: the actuator displacement
``p(t)`` of the quintic stroke (:func:`...physics.kinematics.stroke_eval`) times the
deformation shape.
"""
from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from ...physics.dynamics_kernel import OUTCOMES
from ...physics.kinematics import stroke_eval
from ...physics.trajectory import FiringTrajectory

MAX_FRAMES_PER_STROKE = 1000


class FrameState(NamedTuple):
    """What one frame shows (SI units)."""

    t: float          # simulated time [s]
    x: float          # part position [m]
    amplitude: float  # actuator displacement p(t) [m] (0: flat surface)
    xa: float         # position of the firing actuator [m] (nan: none)
    fired: int        # actuators fired so far (the firing one counts once its stroke started)
    firing: int       # index of the actuator firing now (-1: none)
    target: float     # target [m]
    label: str        # what is happening (for the title)


def check_frames_per_stroke(n: object, render_mode: str | None) -> int:
    """``render_frames_per_stroke``: an integer in [1, MAX_FRAMES_PER_STROKE]; above 1 only with a
    render mode that shows every frame (``rgb_array_list``, ``human``)."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) \
            or not 1 <= n <= MAX_FRAMES_PER_STROKE:
        raise ValueError(f"render_frames_per_stroke = {n!r} is invalid: must be an integer in "
                         f"[1, {MAX_FRAMES_PER_STROKE}]")
    if n > 1 and render_mode not in ("rgb_array_list", "human"):
        raise ValueError(f"render_frames_per_stroke = {n} needs render_mode 'rgb_array_list' or "
                         f"'human' (got {render_mode!r}): 'rgb_array' returns one frame per "
                         "render() call, the state after the step")
    return int(n)


def pick(times: np.ndarray, start: float, end: float, n: int) -> list[int]:
    """Indices into ``times`` (sorted) of the last row at or before each of ``n`` evenly spaced
    times in (start, end]; each index once."""
    out: list[int] = []
    if not end > start or times.size == 0:
        return out
    for j in range(1, n + 1):
        i = int(np.searchsorted(times, start + (end - start) * j / n, side="right")) - 1
        if i >= 0 and (not out or i > out[-1]):
            out.append(i)
    return out


def firing_states(traj: FiringTrajectory, k: int, xa: float, f: float, h: float,
                  target: float, n: int) -> list[FrameState]:
    """Up to ``n`` frames per moving phase of firing ``k`` (actuator at ``xa`` [m], ``f`` [Hz],
    ``h`` [m]): the slide during the delay, the stroke, the slide to rest (module docstring)."""
    t = traj.t_s
    ts, te = traj.stroke_start_s, traj.stroke_end_s
    stroke_text = f"stroke {k + 1}: {f:.0f} Hz, {h * 1e6:.0f} µm"
    phases = (  # (rows, start of the phase, label, fired, firing)
        (t < ts, float(t[0]) if t.size else ts, f"sliding, then {stroke_text}", k, -1),
        ((t >= ts) & (t <= te), ts, stroke_text, k, k),
        (t > te, te, f"after {stroke_text}: sliding", k + 1, -1),
    )
    states: list[FrameState] = []
    for rows, start, label, fired, firing in phases:
        idx = np.flatnonzero(rows)
        if idx.size == 0:
            continue
        for i in idx[pick(t[idx], start, float(t[idx].max()), n)]:
            ti = float(t[i])  # stroke_eval is 0 outside the stroke: the surface is flat there
            states.append(FrameState(ti, float(traj.x_m[i]), float(stroke_eval(ti - ts, f, h)[0]),
                                     xa if firing >= 0 else math.nan, fired, firing, target,
                                     label))
    outcome = OUTCOMES[traj.outcome]
    if outcome != "moving":  # the state it ended in (detached: the moment it left the surface)
        during = ts <= traj.t < ts + 1.0 / f
        states.append(FrameState(traj.t, traj.x, float(stroke_eval(traj.t - ts, f, h)[0]),
                                 xa if during else math.nan, k + 1, k if during else -1, target,
                                 f"{stroke_text}: {outcome.replace('_', ' ')}"))
    return states


class EnvRenderer:
    """The single env's rendering in the modes that show every frame (``rgb_array_list``,
    ``human``): the states not yet rendered, the drawer and the window.

    With ``n`` = 1 a frame per reset and per step, the state after it, as
    :func:`..rail.render.render_frame` draws it for ``rgb_array`` (what gymnasium's
    ``RenderCollection`` would collect); with ``n`` > 1 the frames of each firing
    (:func:`firing_states`), its trajectory recomputed from the state before the step by the
    very compiled firing the step ran (:func:`...physics.trajectory.firing_trajectory`; checked to
    end where the step ended, so rendering cannot change a step's result)."""

    def __init__(self, env: Any, mode: str | None, n: int) -> None:
        self.env = env
        self.n = n
        self.collecting = mode in ("rgb_array_list", "human")
        self.pending: list[Any] = []
        self.drawer: Any = None
        self.window: Any = None
        if mode == "human":
            from ..core.window import Window

            self.window = Window(f"MicroConveyor ({env.config.preset})")

    def _now(self, label: str) -> Any:
        e = self.env
        if self.n == 1:  # render_frame's arguments
            return (e.x, e.target, e.fired, e._last_firing, e.t)
        return FrameState(e.t, e.x, 0.0, math.nan, e.fired, -1, e.target, label)

    def reset(self) -> None:
        if self.collecting:
            self.pending = [self._now("start")]

    def fired(self, k: int, before: tuple[float, float, float], f: float, h: float, d: float,
              outcome: str) -> None:
        """Firing ``k`` (``f`` [Hz], ``h`` [m], delay ``d`` [s]) ran from ``before`` = (x, v, t)."""
        if self.n == 1:
            self.pending.append(self._now(""))
            return
        from ...physics.trajectory import Firing, Integration, firing_trajectory

        e = self.env
        c, cfg = e.conveyor, e.config
        xa = float(c.positions[k])
        to_rest = k == cfg.n_actuators - 1 or outcome == "rest"  # the last, or delivered
        traj = firing_trajectory(before, Firing(xa, f, h, d),
                                 Integration(c.consts.dt, c.consts.min_steps, to_rest,
                                             cfg.max_time),
                                 c.consts.P[0], (c.consts.tu, c.consts.tq, c.consts.tqu))
        if (traj.x, traj.v, traj.t) != (e.x, e.v, e.t):
            raise RuntimeError(f"rendering: the recorded firing ended at x = {traj.x!r} m, "
                               f"t = {traj.t!r} s, the step at x = {e.x!r} m, t = {e.t!r} s "
                               "(please report it)")
        self.pending.extend(firing_states(traj, k, xa, f, h, e.target, self.n))

    def frames(self) -> list[np.ndarray]:
        """The frames of every state since the last call (drawn now)."""
        from ..rail.render import FrameDrawer, render_frame

        items, self.pending = self.pending, []
        if self.n == 1:
            return [render_frame(self.env.config, *s) for s in items]
        if self.drawer is None:
            self.drawer = FrameDrawer(self.env.config)
        return [self.drawer.draw(s) for s in items]

    def show(self, fps: float) -> None:
        """``human``: show the frames since the last call in the window."""
        self.window.show(self.frames(), fps)

    def close(self) -> None:
        if self.window is not None:
            self.window.close()
        self.drawer = None

    def __getstate__(self) -> dict[str, Any]:  # the figure and the window are made anew
        state = self.__dict__.copy()
        state["drawer"] = None
        state["window"] = None if self.window is None else self.window.title
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        if self.window is not None:
            from ..core.window import Window

            self.window = Window(state["window"])
