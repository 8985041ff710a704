"""The simulator API: a preset + a scene -> ``simulate(schedule, x0, v0) -> Result``.

The Python layer validates inputs and builds plain arrays; :mod:`.dynamics_kernel` integrates.
"""
from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import dynamics_kernel as kernel
from . import forces
from .contact_table import ContactTable, TableRangeError
from .kinematics import SHAPES, zone_strain
from .materials import G0, ContactParams, ParameterError, check_range
from .schedule import Schedule
# validators shared with the env's configuration (envs/line/config.py), importable from here as before
from .validation import KINEMATICS, MAX_STEPS, MAX_STEPS_LIMIT, MIN_DT, MIN_WAVELENGTH, \
    RENAMED_KINEMATICS, _check_budget, check_max_steps, check_step_budget, kinematics_level, \
    stroke_steps  # noqa: F401

MODES = {"karnopp": forces.KARNOPP, "event": forces.EVENT}
ROUGHNESS = ("constant", "stretch")
DEFAULT_MODE = "event"
DEFAULT_DT = 5e-5          # s; the accuracy study's pick (event mode, within 1 um; docs/validation.md)
MIN_STEPS_PER_STROKE = 20  # default floor on steps per stroke; below it a warning is issued
PEAK_QUINTIC_ACCEL = 10.0 / math.sqrt(3.0)  # max |p''| in units of h / (T/2)^2


class StepSizeWarning(UserWarning):
    """The time step resolves a stroke with fewer than MIN_STEPS_PER_STROKE steps."""


@dataclass
class Result:
    """Outcome of one simulation (SI units).

    ``outcome`` is ``rest`` (at rest on the still surface from ``rest_time_s`` on; a part that is
    stuck when the last stroke ends rests from that moment), ``detached`` (left the surface
    at ``detach_time_s``/``detach_position_m``), ``max_time`` (still moving at ``max_time``),
    ``moving`` (the state at the end of the last stroke, ``to_rest=False``) or
    ``too_many_events`` (stick-slip chattering the event mode could not resolve). A load beyond the
    contact table raises :class:`TableRangeError` instead of returning a result.
    """

    x0_m: float
    final_position_m: float
    final_velocity_m_s: float
    outcome: str
    end_time_s: float
    rest_time_s: float | None
    detach_time_s: float | None
    detach_position_m: float | None
    steps: int
    events: int
    wall_time_s: float
    trajectory: dict[str, np.ndarray] | None = field(default=None, repr=False)

    @property
    def displacement_m(self) -> float:
        """``final_position_m - x0_m`` [m]."""
        return self.final_position_m - self.x0_m

    def to_dict(self) -> dict[str, Any]:
        """The fields (SI, unit-suffixed keys) without the trajectory, plus ``displacement_m``."""
        d = {k: v for k, v in self.__dict__.items() if k != "trajectory"}
        d["displacement_m"] = self.displacement_m
        return d


@dataclass(frozen=True)
class Stretch:
    """Stretch-dependent roughness (docs/physics.md §4), the settings of
    ``Simulator(roughness=Stretch(...))`` (``roughness="stretch"``: these defaults).

    ``zone_length``: length of the active zone centred on the firing actuator [m] (None: the
    wavelength); outside it the surface under the part is unstrained. ``max_strain``,
    ``n_sigma``: the strain range, from 0 to ``max_strain`` (dimensionless), and the number of
    sigma nodes of the tables (:mod:`.stretch`)."""

    zone_length: float | None = None
    max_strain: float = 0.4
    n_sigma: int = 21


STRETCH_FIELDS = ("zone_length", "max_strain", "n_sigma")


class Simulator:
    """Part dynamics on an actuated surface.

    Parameters
    ----------
    contact : ContactParams (a preset by name: :func:`microconveyor_env.presets.simulator`).
    shape : deformation shape, one of ``gaussian``, ``sinusoidal``, ``clamped_beam``.
    wavelength : deformation wavelength WL [m] (> 0).
    kinematics : ``reduced`` (drops the velocity terms of the normal load, the dissertation's model)
        or ``exact``.
    mode : ``event`` (stick/slip and detachment located inside the step) or ``karnopp``.
    dt : largest RK4 step [s]; each stroke of duration T = 1/f uses the smallest even number of
        steps n with T/n <= dt and n >= ``min_steps``.
    min_steps : floor on the number of steps per stroke (default 20, so fast strokes stay
        resolved whatever dt is); fewer than 20 steps per stroke gives a StepSizeWarning.
    slope : constant tilt of the carrier, tan(angle) [-] (0: horizontal).
    max_time : simulated-time limit [s].
    roughness : ``constant`` (the preset's sigma), ``stretch`` or a :class:`Stretch` of its
        settings (docs/physics.md §4: the strain of the active zone under the part sets sigma,
        and Q(N) and the pull-off force follow it; tables over ``n_sigma`` strains in
        [0, ``max_strain``], see :mod:`.stretch`). :meth:`from_keywords` (and
        :func:`microconveyor_env.presets.simulator`) also take the settings as keywords
        (``roughness="stretch", n_sigma=11``).
    max_steps : cap on the RK4 steps of one :meth:`simulate` call (default ``MAX_STEPS``, 1e7:
        seconds of computing); a schedule needing more is refused up front. Raise it if you mean it.
    """

    def __init__(self, contact: ContactParams, shape: str = "gaussian", wavelength: float = 0.6e-3,
                 kinematics: str = "reduced", mode: str = DEFAULT_MODE, dt: float = DEFAULT_DT,
                 slope: float = 0.0, max_time: float = 10.0,
                 min_steps: int = MIN_STEPS_PER_STROKE, max_steps: int = MAX_STEPS,
                 roughness: str | Stretch = "constant") -> None:
        if not isinstance(contact, ContactParams):
            raise ParameterError(f"contact = {contact!r} is invalid: Simulator takes ContactParams; "
                                 "for a preset by name use microconveyor_env.presets.simulator("
                                 "name, ...)")
        if shape not in SHAPES:
            raise ParameterError(f"shape = {shape!r} is invalid: must be one of {sorted(SHAPES)}")
        kinematics = kinematics_level(kinematics, "Simulator")
        if mode not in MODES:
            raise ParameterError(f"mode = {mode!r} is invalid: must be one of {sorted(MODES)}")
        stretch: Stretch | None = roughness if isinstance(roughness, Stretch) else None
        if stretch is None and roughness not in ROUGHNESS:
            raise ParameterError(f"roughness = {roughness!r} is invalid: must be one of "
                                 f"{ROUGHNESS} or a Stretch")
        if roughness == "stretch":
            stretch = Stretch()
        self.roughness = "constant" if stretch is None else "stretch"
        self.contact = contact
        self.shape, self.kinematics, self.mode = shape, kinematics, mode
        self.wavelength = check_range("Simulator", "wavelength", wavelength, MIN_WAVELENGTH, 1.0,
                                      unit="m")
        self.dt = check_range("Simulator", "dt", dt, MIN_DT, 1.0, unit="s")
        if isinstance(min_steps, bool) or not isinstance(min_steps, (int, np.integer)) \
                or not 2 <= min_steps <= 10 ** 7:
            raise ParameterError(f"Simulator.min_steps = {min_steps!r} is invalid: must be an "
                                 "integer in [2, 1e7]")
        self.min_steps = int(min_steps)
        self.max_steps = check_max_steps("Simulator", max_steps)
        self.slope = check_range("Simulator", "slope", slope, -100, 100)
        self.max_time = check_range("Simulator", "max_time", max_time, 0, math.inf, True, unit="s")
        self.table = ContactTable(contact)
        self.table.check_weight()
        self.mass = contact.part.mass
        P = np.zeros(forces.N_PARAMS)
        P[forces.I_MASS], P[forces.I_G0] = self.mass, G0
        P[forces.I_NMIN] = -self.table.pull_off_force
        P[forces.I_EXACT] = 1.0 if kinematics == "exact" else 0.0
        P[forces.I_SLOPE], P[forces.I_WL] = self.slope, self.wavelength
        P[forces.I_SHAPE], P[forces.I_MODE] = SHAPES[shape], MODES[mode]
        P[forces.I_NMAX] = self.table.max_load
        P[forces.I_FSCALE] = 1.0
        self.params = P
        tu, tq, tqu, _ = self.table.kernel_arrays()
        self.tables: tuple[np.ndarray, ...] = (np.ascontiguousarray(tu), np.ascontiguousarray(tq),
                              np.ascontiguousarray(tqu))
        self.stretch: Any = None  # StretchContact with roughness='stretch'
        if stretch is not None:
            self._setup_stretch(stretch)

    @classmethod
    def from_keywords(cls, contact: ContactParams, **kw: Any) -> Simulator:
        """``Simulator(contact, **kw)`` where ``kw`` may also hold the fields of the
        :class:`Stretch` settings (``zone_length``, ``max_strain``, ``n_sigma``): with
        ``roughness="stretch"`` they make its ``Stretch``; constant roughness ignores them."""
        settings = {k: kw.pop(k) for k in STRETCH_FIELDS if k in kw}
        if settings and kw.get("roughness") == "stretch":
            kw["roughness"] = Stretch(**settings)
        return cls(contact, **kw)

    # ------------------------------------------------------------------ stretch
    def _setup_stretch(self, settings: Stretch) -> None:
        from .stretch import StretchContact, pack_tables, strain_table

        zone_length, max_strain, n_sigma = settings.zone_length, settings.max_strain, \
            settings.n_sigma
        zone = self.wavelength if zone_length is None else check_range(
            "Simulator", "zone_length", zone_length, 0, 1.0, True, unit="m")
        self.zone_length = zone
        self.stretch = StretchContact(self.contact, max_strain=max_strain, n_sigma=n_sigma)
        pk = pack_tables(self.stretch)
        shape = SHAPES[self.shape]
        # amplitude at which the zone reaches max_strain (strain grows monotonically with it)
        lo, hi = 0.0, self.wavelength
        while zone_strain(hi, shape, self.wavelength, zone) < pk["max_strain"]:
            hi *= 2.0
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if zone_strain(mid, shape, self.wavelength, zone) < pk[
                "max_strain"] else (lo, mid)
        self.max_stretch_amplitude = lo
        step, e = strain_table(shape, self.wavelength, zone, hi)
        n_sig = pk["n_sigma"]
        P = np.concatenate([self.params, pk["offsets"], pk["n_min"], e])
        P[forces.I_STRETCH], P[forces.I_ZONE], P[forces.I_A2STEP] = 1.0, 0.5 * zone, step
        P[forces.I_NSTRAIN], P[forces.I_NSIG], P[forces.I_EMAX] = e.size, n_sig, pk["max_strain"]
        P[forces.I_NMIN] = pk["n_min"][0]
        P[forces.I_NMAX] = self.stretch_max_load = pk["max_load"]
        self.params = P
        # (1, L) arrays: their dimension selects the stretch lookup when the kernel is compiled
        # (forces.friction_at), so the constant-roughness code carries no stretch test at all
        self.tables = tuple(np.ascontiguousarray(pk[k]).reshape(1, -1) for k in ("u", "q", "q_u"))

    def peak_strain(self, stroke: float) -> float:
        """Strain of the active zone at full stroke ``stroke`` [m] (0 without stretch) [-]."""
        if self.stretch is None:
            return 0.0
        return float(zone_strain(float(stroke), SHAPES[self.shape], self.wavelength,
                                 self.zone_length))

    # ------------------------------------------------------------------ checks
    def check_firings(self, f: np.ndarray, h: np.ndarray, mass_factor: float = 1.0) -> None:
        """Warn about under-resolved strokes at frequencies ``f`` [Hz] and strokes ``h`` [m];
        refuse loads beyond the contact table and more steps than ``max_steps``. ``mass_factor``
        [-] checks the loads of a part that much heavier (the table does not depend on the mass,
        only the load does)."""
        steps = stroke_steps(f, self.dt, self.min_steps)
        _check_budget("Simulator", f, self.dt, steps, self.max_steps, self.max_time)
        if steps.min() < MIN_STEPS_PER_STROKE:
            warnings.warn(f"dt = {self.dt:g} s resolves the fastest stroke (f = {f.max():g} Hz) "
                          f"with {int(steps.min())} steps (< {MIN_STEPS_PER_STROKE}); results may "
                          "be inaccurate: reduce dt", StepSizeWarning, stacklevel=3)
        if self.stretch is not None and h.max() > self.max_stretch_amplitude:
            raise ParameterError(f"a stroke of {h.max():g} m strains the active zone beyond the "
                                 f"stretch tables' max_strain = {self.stretch.max_strain}: raise "
                                 "max_strain")
        peak = self.mass * mass_factor * (G0 + PEAK_QUINTIC_ACCEL * h * (2 * f) ** 2)
        if self.kinematics == "exact":
            peak = peak * 4.0  # generous room for the velocity terms
        # the tables' range (with stretch: the smallest over the sigma nodes)
        max_load = self.table.max_load if self.stretch is None else self.stretch_max_load
        if peak.max() > max_load:
            raise TableRangeError(f"a stroke (f = {f.max():g} Hz, h = {h.max():g} m) can load the "
                                  f"part up to {peak.max():.3g} N, beyond the contact table "
                                  f"({max_load:.3g} N)")

    # ------------------------------------------------------------------ runs
    def simulate(self, schedule: Schedule, x0: float, v0: float = 0.0, record: bool = False,
                 to_rest: bool = True) -> Result:
        """Run ``schedule`` from position ``x0`` [m] and velocity ``v0`` [m/s] at t = 0."""
        if not isinstance(schedule, Schedule):
            raise ParameterError(f"schedule must be a Schedule, got {type(schedule).__name__}")
        x0 = check_range("simulate", "x0", x0, -1.0, 1.0, unit="m")
        v0 = check_range("simulate", "v0", v0, -100.0, 100.0, unit="m/s")
        xa, f, h, d = schedule.arrays()
        self.check_firings(f, h)
        cap = 0
        if record:
            cap = (int(stroke_steps(f, self.dt, self.min_steps).sum()) * 2
                   + (12 + 2 * kernel.COAST_POINTS) * len(f) + 64)
        rec = np.zeros((cap, kernel.N_REC))
        out = np.zeros(kernel.N_OUT)
        t0 = time.perf_counter()
        kernel.run(xa, f, h, d, x0, v0, 0.0, self.dt, self.min_steps, to_rest,  # type: ignore[call-arg]
              self.max_time, self.params, *self.tables, rec, out)
        wall = time.perf_counter() - t0
        return self._result(out, x0, rec, wall, record)

    def _result(self, out: np.ndarray, x0: float, rec: np.ndarray, wall: float,
                record: bool) -> Result:
        outcome = kernel.OUTCOMES[int(out[kernel.O_OUTCOME])]
        if outcome == "load_beyond_table":
            raise TableRangeError(f"the normal load exceeded the contact table "
                                  f"({self.table.max_load:.3g} N) at t = {out[kernel.O_EVENT_T]:.6g} s, "
                                  f"x = {out[kernel.O_EVENT_X]:.6g} m; rebuild it with a larger load_ratio")
        detached = outcome == "detached"
        traj = None
        if record:
            n = int(out[kernel.O_NREC])
            r = rec[:n]
            traj = {"t_s": r[:, kernel.R_T], "x_m": r[:, kernel.R_X], "v_m_s": r[:, kernel.R_V],
                    "y_m": r[:, kernel.R_Y], "N_N": r[:, kernel.R_N], "Q_N": r[:, kernel.R_Q],
                    "F_N": r[:, kernel.R_F], "stick": r[:, kernel.R_STICK] > 0.5}
        return Result(
            x0_m=x0, final_position_m=float(out[kernel.O_X]), final_velocity_m_s=float(out[kernel.O_V]),
            outcome=outcome, end_time_s=float(out[kernel.O_T]),
            rest_time_s=float(out[kernel.O_T]) if outcome == "rest" else None,
            detach_time_s=float(out[kernel.O_EVENT_T]) if detached else None,
            detach_position_m=float(out[kernel.O_EVENT_X]) if detached else None,
            steps=int(out[kernel.O_STEPS]), events=int(out[kernel.O_EVENTS]), wall_time_s=wall,
            trajectory=traj)

    def steps_per_stroke(self, frequency: float) -> int:
        """RK4 steps [-] of one stroke at ``frequency`` [Hz]."""
        f = check_range("Simulator", "frequency", frequency, 0, math.inf, True, unit="Hz")
        check_step_budget("Simulator", f, self.dt, self.min_steps, self.max_steps)
        return int(kernel.steps_for(f, self.dt, self.min_steps))

    def flat_deceleration(self) -> float:
        """Deceleration of a sliding part on the flat, still surface, Q(m g0)/m [m/s^2]."""
        return float(self.table.friction(self.mass * G0)) / self.mass
