"""The plane simulator's Python front end (docs/physics.md §10): a grid of actuators under a
surface, a part at ``(x, y)`` with velocity ``(vx, vy)``; ``simulate(schedule, ...)`` returns a
:class:`PlaneResult`.

The Python layer validates and builds plain arrays; :mod:`.plane_kernel` integrates (event mode
only). The contact table, the model constants and the firing checks are the 1-D
:class:`..simulator.Simulator`'s, built with the same arguments, so a scene on one line of the plane
is the 1-D scene.

For a compiled caller (a batched env): ``PlaneSimulator.params`` and ``PlaneSimulator.tables`` are
the arguments ``P, tu, tq, tqu`` of :func:`.kernel.fire` and :func:`.kernel.coast`.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import kernel
from ..contact_table import TableRangeError
from ..materials import ContactParams, ParameterError, check_range
from ..dynamics_kernel import COAST_POINTS, OUTCOMES
from ..schedule import Firing, checked_firings
from ..simulator import DEFAULT_DT, MIN_STEPS_PER_STROKE, Simulator
from ..validation import MAX_STEPS, stroke_steps


@dataclass(frozen=True)
class ActuatorGrid:
    """Actuator positions in the plane, ``((x, y), ...)`` [m], all distinct."""

    positions: tuple[tuple[float, float], ...]

    def __post_init__(self) -> None:
        pos = []
        for i, p in enumerate(self.positions):
            if not isinstance(p, (tuple, list, np.ndarray)) or len(p) != 2:
                raise ParameterError(f"ActuatorGrid.positions[{i}] = {p!r} is invalid: must be "
                                     "an (x, y) pair [m]")
            pos.append((check_range("ActuatorGrid", f"positions[{i}][0]", p[0], -1.0, 1.0,
                                    unit="m"),
                        check_range("ActuatorGrid", f"positions[{i}][1]", p[1], -1.0, 1.0,
                                    unit="m")))
        if not pos:
            raise ParameterError("ActuatorGrid.positions is empty: need at least one actuator")
        if len(set(pos)) != len(pos):
            raise ParameterError("ActuatorGrid.positions has two actuators at the same place")
        object.__setattr__(self, "positions", tuple(pos))

    @classmethod
    def regular(cls, nx: int, ny: int, spacing: float,
                origin: tuple[float, float] = (0.0, 0.0)) -> ActuatorGrid:
        """``nx`` x ``ny`` [-] actuators ``spacing`` [m] apart, the first at ``origin`` [m]; index
        ``i + nx j`` is the one at ``origin + spacing (i, j)``."""
        n_x = int(check_range("ActuatorGrid", "nx", nx, 1, 1000))
        n_y = int(check_range("ActuatorGrid", "ny", ny, 1, 1000))
        sp = check_range("ActuatorGrid", "spacing", spacing, 0, 1.0, True, unit="m")
        return cls(tuple((origin[0] + sp * i, origin[1] + sp * j)
                         for j in range(n_y) for i in range(n_x)))

    def __len__(self) -> int:
        return len(self.positions)


@dataclass(frozen=True)
class PlaneSchedule:
    """Firings (the 1-D :class:`..schedule.Firing`: actuator index, frequency [Hz], stroke [m],
    delay [s]) on an :class:`ActuatorGrid`."""

    grid: ActuatorGrid
    firings: tuple[Firing, ...]

    def __post_init__(self) -> None:
        if not isinstance(self.grid, ActuatorGrid):
            raise ParameterError(f"PlaneSchedule.grid must be an ActuatorGrid, got "
                                 f"{type(self.grid).__name__}")
        object.__setattr__(self, "firings",
                           checked_firings(self.firings, len(self.grid), "PlaneSchedule", "grid"))

    def arrays(self) -> tuple[np.ndarray, ...]:
        """(x_act [m], y_act [m], f [Hz], h [m], delay [s]) as float64 arrays over the firings."""
        pos = np.array([self.grid.positions[f.actuator] for f in self.firings],
                       dtype=float).reshape(-1, 2)
        f = np.array([fi.frequency for fi in self.firings], dtype=float)
        h = np.array([fi.stroke for fi in self.firings], dtype=float)
        d = np.array([fi.delay for fi in self.firings], dtype=float)
        return np.ascontiguousarray(pos[:, 0]), np.ascontiguousarray(pos[:, 1]), f, h, d


@dataclass
class PlaneResult:
    """Outcome of one plane simulation (SI units); outcomes as :class:`..simulator.Result`."""

    start_m: tuple[float, float]
    final_position_m: tuple[float, float]
    final_velocity_m_s: tuple[float, float]
    outcome: str
    end_time_s: float
    rest_time_s: float | None
    detach_time_s: float | None
    detach_position_m: tuple[float, float] | None
    steps: int
    events: int
    wall_time_s: float
    trajectory: dict[str, np.ndarray] | None = field(default=None, repr=False)

    @property
    def displacement_m(self) -> float:
        """Distance [m] from the start to the final position."""
        return math.hypot(self.final_position_m[0] - self.start_m[0],
                          self.final_position_m[1] - self.start_m[1])


class PlaneSimulator:
    """Part dynamics on a surface over the plane, deformed by one actuator of a grid at a time.

    Parameters (as :class:`..simulator.Simulator`, whose contact table and checks this uses)
    ----------
    contact : ContactParams (a preset's ``.contact``).
    shape : radial deformation shape, ``gaussian``, ``sinusoidal`` or ``clamped_beam``.
    wavelength : shape wavelength WL [m].
    kinematics : ``reduced`` (default) or ``exact`` (keeps ``2 grad Z_t . v + v^T Hess Z v``).
    dt : largest RK4 step [s]; min_steps : floor on the steps per stroke [-].
    max_time : simulated-time limit [s]; max_steps : cap on the RK4 steps of one call [-].

    The integrator is the event mode (no Karnopp mode in the plane), the plane is level (no tilt)
    and the roughness constant (no stretch).
    """

    def __init__(self, contact: ContactParams, shape: str = "gaussian", wavelength: float = 0.6e-3,
                 kinematics: str = "reduced", dt: float = DEFAULT_DT, max_time: float = 10.0,
                 min_steps: int = MIN_STEPS_PER_STROKE, max_steps: int = MAX_STEPS) -> None:
        self.line = Simulator(contact, shape=shape, wavelength=wavelength, kinematics=kinematics,
                              mode="event", dt=dt, max_time=max_time, min_steps=min_steps,
                              max_steps=max_steps)
        self.contact, self.shape, self.kinematics = contact, shape, self.line.kinematics
        self.wavelength, self.dt, self.min_steps = self.line.wavelength, self.line.dt, \
            self.line.min_steps
        self.max_time, self.max_steps, self.mass = self.line.max_time, self.line.max_steps, \
            self.line.mass
        self.table = self.line.table
        self.params: np.ndarray = self.line.params
        self.tables: tuple[np.ndarray, ...] = self.line.tables

    def simulate(self, schedule: PlaneSchedule, x0: float, y0: float, vx0: float = 0.0,
                 vy0: float = 0.0, record: bool = False, to_rest: bool = True) -> PlaneResult:
        """Run ``schedule`` from ``(x0, y0)`` [m] with velocity ``(vx0, vy0)`` [m/s] at t = 0."""
        if not isinstance(schedule, PlaneSchedule):
            raise ParameterError(f"schedule must be a PlaneSchedule, got "
                                 f"{type(schedule).__name__}")
        x0, y0 = (check_range("simulate", n, v, -1.0, 1.0, unit="m")
                  for n, v in (("x0", x0), ("y0", y0)))
        vx0, vy0 = (check_range("simulate", n, v, -100.0, 100.0, unit="m/s")
                    for n, v in (("vx0", vx0), ("vy0", vy0)))
        xa, ya, f, h, d = schedule.arrays()
        if f.size:
            self.check_firings(f, h)
        cap = 0
        if record:
            cap = (int(stroke_steps(f, self.dt, self.min_steps).sum()) * 2
                   + (12 + 2 * COAST_POINTS) * len(f) + 64)
        rec = np.zeros((cap, kernel.N_REC))
        out = np.zeros(kernel.N_OUT)
        t0 = time.perf_counter()
        kernel.run(xa, ya, f, h, d, x0, y0, vx0, vy0, 0.0,  # type: ignore[call-arg]
                   self.dt, self.min_steps, to_rest, self.max_time, self.params, *self.tables, rec,
                   out)
        wall = time.perf_counter() - t0
        return self._result(out, (x0, y0), rec[:int(out[kernel.O_NREC])] if record else None,
                            wall)

    def _result(self, out: np.ndarray, start: tuple[float, float], rec: np.ndarray | None,
                wall: float) -> PlaneResult:
        outcome = OUTCOMES[int(out[kernel.O_OUTCOME])]
        if outcome == "load_beyond_table":
            raise TableRangeError(f"the normal load exceeded the contact table "
                                  f"({self.table.max_load:.3g} N) at t = "
                                  f"{out[kernel.O_EVENT_T]:.6g} s; rebuild it with a larger "
                                  "load_ratio")
        detached = outcome == "detached"
        traj: dict[str, Any] | None = None
        if rec is not None:
            traj = {"t_s": rec[:, kernel.R_T], "x_m": rec[:, kernel.R_X], "y_m": rec[:, kernel.R_Y],
                    "vx_m_s": rec[:, kernel.R_VX], "vy_m_s": rec[:, kernel.R_VY],
                    "z_m": rec[:, kernel.R_Z], "N_N": rec[:, kernel.R_N], "Q_N": rec[:, kernel.R_Q],
                    "stick": rec[:, kernel.R_STICK] > 0.5}
        return PlaneResult(
            start_m=start, final_position_m=(float(out[kernel.O_X]), float(out[kernel.O_Y])),
            final_velocity_m_s=(float(out[kernel.O_VX]), float(out[kernel.O_VY])),
            outcome=outcome, end_time_s=float(out[kernel.O_T]),
            rest_time_s=float(out[kernel.O_T]) if outcome == "rest" else None,
            detach_time_s=float(out[kernel.O_EVENT_T]) if detached else None,
            detach_position_m=(float(out[kernel.O_EVENT_X]), float(out[kernel.O_EVENT_Y]))
            if detached else None,
            steps=int(out[kernel.O_STEPS]), events=int(out[kernel.O_EVENTS]), wall_time_s=wall,
            trajectory=traj)

    def check_firings(self, f: np.ndarray, h: np.ndarray, mass_factor: float = 1.0) -> None:
        """The 1-D checks of firings at frequencies ``f`` [Hz] with strokes ``h`` [m] (the step
        budget, under-resolved strokes, loads beyond the contact table for a part ``mass_factor``
        [-] times heavier): :meth:`..simulator.Simulator.check_firings`."""
        self.line.check_firings(np.asarray(f, dtype=float), np.asarray(h, dtype=float),
                                mass_factor)

    def steps_per_stroke(self, frequency: float) -> int:
        """RK4 steps [-] of one stroke at ``frequency`` [Hz] (as on the line)."""
        return self.line.steps_per_stroke(frequency)

    def flat_deceleration(self) -> float:
        """Deceleration of a part sliding on the still plane, Q(m g0)/m [m/s^2]."""
        return self.line.flat_deceleration()
