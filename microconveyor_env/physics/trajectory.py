"""The trajectory of one firing, as the env fires it: :func:`.dynamics_kernel.fire` run again with
its trajectory recording on (for pictures; SI units).

Recording only appends rows (:func:`.dynamics_kernel._record`): the state is integrated by the
same compiled code with the same inputs, so the run ends in the very state (bit for bit) the
firing without recording ended in. The rows are real states of the simulation, never
interpolated: the delay's closed-form coast (its start, then ``COAST_POINTS`` rows evenly over
its moving part), the stroke (its start, every RK4 step and every located stick/slip/detachment
event) and, with ``to_rest``, the coast to rest (``COAST_POINTS`` rows).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from . import dynamics_kernel as kernel


class FiringTrajectory(NamedTuple):
    """Rows of one firing (time order) and where it ended."""

    t_s: np.ndarray        # (n,) simulated time of each row [s]
    x_m: np.ndarray        # (n,) part position [m]
    v_m_s: np.ndarray      # (n,) part velocity [m/s]
    y_m: np.ndarray        # (n,) surface height under the part [m]
    stroke_start_s: float  # when the stroke starts (after the delay) [s]
    stroke_end_s: float    # when it ends: t + delay + 1/f, or the event that cut it [s]
    x: float               # final state, exactly as the firing without recording
    v: float
    t: float
    outcome: int           # dynamics_kernel outcome code


def row_capacity(f: float, dt: float, min_steps: int) -> int:
    """Rows enough for any firing at ``f`` [Hz]: every step with its most events, two coasts."""
    steps = int(kernel.steps_for(f, dt, min_steps)) + 2  # + the event mode's two extra nodes
    return steps * (kernel.MAX_EVENTS_PER_STEP + 3) + 2 * kernel.COAST_POINTS + 16


class Firing(NamedTuple):
    """One firing: the actuator at ``xa`` [m] strokes ``h`` [m] at ``f`` [Hz] after ``delay``
    [s]."""

    xa: float
    f: float
    h: float
    delay: float


class Integration(NamedTuple):
    """How a firing is integrated: largest RK4 step ``dt`` [s], at least ``min_steps`` steps a
    stroke, ``to_rest`` (coast to rest after the stroke), time limit ``t_max`` [s]."""

    dt: float
    min_steps: int
    to_rest: bool
    t_max: float


def firing_trajectory(state: tuple[float, float, float], firing: Firing, run: Integration,
                      P: np.ndarray,
                      tables: tuple[np.ndarray, np.ndarray, np.ndarray]) -> FiringTrajectory:
    """Fire ``firing`` from the part's ``state`` = (x [m], v [m/s], t [s]) as
    :func:`.dynamics_kernel.fire` does with the same arguments (``run``: its integration
    settings), recording the trajectory. ``P`` is the row of physics constants the firing used
    (an env's part: its own row, with this episode's mass and friction factors); ``tables`` the
    contact tables ``(tu, tq, tqu)``."""
    x, v, t = state
    xa, f, h, delay = firing
    dt, min_steps, to_rest, t_max = run
    tu, tq, tqu = tables
    rec = np.zeros((row_capacity(f, dt, min_steps), kernel.N_REC))
    out = np.zeros(kernel.N_OUT)
    kernel.reset_out(out)
    xe, ve, te, code = kernel.fire(float(x), float(v), float(t), float(xa), float(f), float(h),
                                   float(delay), float(dt), int(min_steps), bool(to_rest),
                                   float(t_max), P, tu, tq, tqu, rec, out)
    r = rec[:int(out[kernel.O_NREC])]
    start = float(t) + float(delay)
    end = start + 1.0 / float(f)
    if out[kernel.O_EVENT_T] >= 0.0:  # the stroke (or the delay) was cut short
        end = min(end, float(out[kernel.O_EVENT_T]))
    return FiringTrajectory(t_s=r[:, kernel.R_T].copy(), x_m=r[:, kernel.R_X].copy(),
                            v_m_s=r[:, kernel.R_V].copy(), y_m=r[:, kernel.R_Y].copy(),
                            stroke_start_s=start, stroke_end_s=end, x=float(xe), v=float(ve),
                            t=float(te), outcome=int(code))
