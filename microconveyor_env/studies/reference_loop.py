"""The firing integrated "the dissertation's way": a plain-Python baseline for speed comparisons.

One actuator (at x = 0) fires once; the part starts at rest at ``x0``. Same physics as the package
kernel in ``karnopp`` mode with ``reduced`` kinematics (docs/physics.md §1-§3):

* surface ``Y = p(t) g(x - x_act)``, Gaussian ``g`` with ``s = WL/6``, quintic stroke ``p`` of
  height ``h`` and duration ``T = 1/f``;
* normal load ``N = m cos(theta) (g0 + Y_tt)`` (velocity terms dropped), slip acceleration
  ``(-s Q cos(theta) - N sin(theta)) / m``, detachment when ``N < -F_pull``;
* ``Q(N)`` from the contact table (:meth:`ContactTable.kernel_arrays`, converted once to Python
  lists), looked up with :mod:`bisect` and the kernel's cubic Hermite formula;
* fixed-step RK4 with the Karnopp velocity threshold ``v_th = Q dt / m``: inside it the part sticks
  if ``|v|`` is decreasing or ``|N tan(theta)| <= Q``, else it slips in the direction of the net
  force (exactly the logic of ``stroke()`` in the kernel's non-event branch).

Unlike the package, there is **no closed-form shortcut**: the coast on the flat, still surface after
the stroke is stepped with the same RK4 + Karnopp and the same ``dt`` until the part sticks with
``v = 0`` (on the flat still surface it then stays). The time grid has ``n = ceil(T/dt)`` steps over
the stroke (dt adjusted to ``T/n``), then the same dt through the coast.

The hot loop is plain Python: ``math`` and ``bisect`` only, Python floats and lists (no numpy, no
numba). numpy/numba are only used outside it (the contact table, the package reference runs).

API
---
``reference_firing(contact, freq, stroke, x0, dt, wavelength) -> dict``
``converged_dt(contact, target_m=1e-6, reference_m=None, **kw) -> dict``

``microconveyor bench`` runs it beside the kernel; ``python -m
microconveyor_env.studies.reference_loop`` prints ``converged_dt`` for the dissertation preset.
"""
from __future__ import annotations

import bisect
import json
import math
import time
from typing import TYPE_CHECKING, Any

from microconveyor_env.physics.contact_table import ContactTable
from microconveyor_env.physics.materials import G0, ContactParams

if TYPE_CHECKING:
    from microconveyor_env.physics.simulator import Result

TableLists = tuple[list[float], list[float], list[float], float]

DEFAULT_DT_START = 2e-5      # s, first (coarsest) step of the convergence search
DEFAULT_TIME_BUDGET = 150.0  # s, wall-clock budget of the whole search (incl. the reference run)
DEFAULT_DT_MIN = 5e-9        # s, hard floor on the step (worst-case search ~15 s here)
MAX_TIME = 10.0              # s, simulated-time limit (as the package Simulator's default)


def _table_lists(contact: ContactParams) -> TableLists:
    """(tu, tq, tqu, n_min [N]) of the contact table as Python lists / float (SI)."""
    tu, tq, tqu, n_min = ContactTable(contact).kernel_arrays()
    return [float(a) for a in tu], [float(a) for a in tq], [float(a) for a in tqu], float(n_min)


# One long function on purpose (120 lines, complexity 14): it is the independent check of the
# compiled kernel, written as the dissertation's single fixed-step loop so that it shares no
# helper, and no mistake, with physics/dynamics_kernel.py; splitting it would re-create the
# kernel's structure it exists to check.
def reference_firing(contact: ContactParams, freq: float = 950.0, stroke: float = 200e-6,
                     x0: float = 0.125e-3, dt: float = 1e-6, wavelength: float = 0.6e-3, *,
                     x_act: float = 0.0, max_time: float = MAX_TIME,
                     _tables: TableLists | None = None) -> dict[str, Any]:
    """One firing integrated with plain-Python fixed-step RK4 + Karnopp, stroke and coast.

    Parameters: ``contact`` a ContactParams (e.g. ``load_preset("feasibility").contact``), ``freq`` [Hz],
    ``stroke`` height h [m], ``x0`` start position [m] (part at rest), ``dt`` nominal step [s]
    (adjusted to ``T/n``, ``n = ceil(T/dt)``), ``wavelength`` WL [m], ``x_act`` actuator [m],
    ``max_time`` simulated-time limit [s].

    Returns a dict: ``displacement_m``, ``final_position_m``, ``rest_time_s`` (time the part came
    to rest, None unless ``outcome == 'rest'``), ``outcome`` ('rest', 'detached', or 'max_time' if
    still moving at ``max_time``), ``steps`` (time steps taken, stroke + coast, including the final
    stick step), ``wall_time_s`` (the integration loop only; the table lookup setup is excluded, as
    the package's ``wall_time_s`` excludes its Python layer), plus ``dt_s`` (the effective step),
    ``stroke_steps`` (n), ``detach_time_s`` and ``detach_position_m`` (None unless detached).
    """
    tu, tq, tqu, n_min = _tables if _tables is not None else _table_lists(contact)
    m = float(contact.part.mass)
    f = float(freq)
    h = float(stroke)
    T = 1.0 / f
    half = 0.5 * T
    inv_half2 = 1.0 / (half * half)
    n = max(int(math.ceil(T / dt - 1e-9)), 1)   # the 1e-9 guards against T/dt = n(1 + eps)
    dt = T / n
    sw = wavelength / 6.0
    inv_s2 = 1.0 / (sw * sw)
    xa = float(x_act)
    nt = len(tu)
    exp, sqrt = math.exp, math.sqrt
    bisect_right = bisect.bisect_right

    def friction(N: float) -> float:
        """Q(N): cubic Hermite in u = sqrt(N - n_min) (N below pull-off clamped to it)."""
        du = N - n_min
        u = sqrt(du) if du > 0.0 else 0.0
        lo = bisect_right(tu, u) - 1
        if lo > nt - 2:
            lo = nt - 2
        elif lo < 0:
            lo = 0
        u0 = tu[lo]
        hh = tu[lo + 1] - u0
        t = (u - u0) / hh
        t2 = t * t
        t3 = t2 * t
        return ((2 * t3 - 3 * t2 + 1) * tq[lo] + (t3 - 2 * t2 + t) * hh * tqu[lo]
                + (-2 * t3 + 3 * t2) * tq[lo + 1] + (t3 - t2) * hh * tqu[lo + 1])

    def load(x: float, t: float) -> tuple[float, float, float]:
        """(N, Y_x, cos(theta)) at position x, time t since the stroke start (reduced kinematics)."""
        if 0.0 <= t <= T:
            if t <= half:
                tau = t / half
            else:                          # mirror image p(t) = p(T - t); p_tt is symmetric
                tau = (T - t) / half
            t2 = tau * tau
            p = h * t2 * tau * (10.0 + tau * (-15.0 + 6.0 * tau))
            p_tt = h * 60.0 * tau * (1.0 + tau * (-3.0 + 2.0 * tau)) * inv_half2
        else:                              # actuator at rest: flat, still surface
            p = p_tt = 0.0
        u = x - xa
        g = exp(-0.5 * u * u * inv_s2)
        Yx = p * (-u * inv_s2 * g)
        c = 1.0 / sqrt(1.0 + Yx * Yx)
        return m * c * (G0 + p_tt * g), Yx, c

    def accel(x: float, t: float, s: float) -> float:
        N, Yx, c = load(x, t)
        return (-s * friction(N) * c - N * Yx * c) / m

    def rk4(x: float, v: float, t: float, hs: float, s: float) -> tuple[float, float]:
        a1 = accel(x, t, s)
        v2 = v + 0.5 * hs * a1
        a2 = accel(x + 0.5 * hs * v, t + 0.5 * hs, s)
        v3 = v + 0.5 * hs * a2
        a3 = accel(x + 0.5 * hs * v2, t + 0.5 * hs, s)
        v4 = v + hs * a3
        a4 = accel(x + hs * v3, t + hs, s)
        return (x + hs / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4),
                v + hs / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4))

    max_steps = n + int(math.ceil(max(max_time - T, 0.0) / dt))
    wall0 = time.perf_counter()
    x, v, t = float(x0), 0.0, 0.0
    k = 0
    outcome = "max_time"
    rest_time: float | None = None
    detach_time: float | None = None
    detach_x: float | None = None
    while k < max_steps:
        t_end = T if k == n - 1 else (k + 1) * dt
        N, Yx, c = load(x, t)
        if N < n_min:                                   # detachment (checked at the step start)
            outcome, detach_time, detach_x = "detached", t, x
            break
        Q = friction(N)
        if abs(v) < Q * dt / m:                         # Karnopp threshold
            sv = 1.0 if v > 0.0 else -1.0
            decreasing = v != 0.0 and v * accel(x, t, sv) < 0.0
            if decreasing or Q >= abs(N * Yx):
                v = 0.0                                 # stick over this step
                k += 1
                if k > n:                               # coasting on the flat still surface:
                    outcome, rest_time = "rest", t      # stuck there means at rest for good
                    break
                t = t_end
                continue
            s = 1.0 if -N * Yx > 0.0 else -1.0          # break away along the net force
        else:
            s = 1.0 if v > 0.0 else -1.0
        x, v = rk4(x, v, t, t_end - t, s)
        t = t_end
        k += 1
    wall = time.perf_counter() - wall0
    return {"displacement_m": x - float(x0), "final_position_m": x, "rest_time_s": rest_time,
            "outcome": outcome, "steps": k, "wall_time_s": wall, "dt_s": dt, "stroke_steps": n,
            "detach_time_s": detach_time, "detach_position_m": detach_x}


def package_displacement(contact: ContactParams, freq: float = 950.0, stroke: float = 200e-6,
                         x0: float = 0.125e-3, dt: float = 1e-6, wavelength: float = 0.6e-3,
                         mode: str = "event") -> Result:
    """The package's answer (``Simulator(contact, mode=mode, dt=dt)``), as a Result: ``freq`` [Hz],
    ``stroke`` [m], ``x0`` [m], ``dt`` [s], ``wavelength`` [m]."""
    from microconveyor_env.physics.schedule import Schedule
    from microconveyor_env.physics.simulator import Simulator

    sim = Simulator(contact, wavelength=wavelength, mode=mode, dt=dt)
    return sim.simulate(Schedule.single(freq, stroke), x0=x0)


def converged_dt(contact: ContactParams, target_m: float = 1e-6, reference_m: float | None = None,
                 *, dt_start: float = DEFAULT_DT_START, time_budget_s: float = DEFAULT_TIME_BUDGET,
                 dt_min: float = DEFAULT_DT_MIN, **kw: Any) -> dict[str, Any]:
    """Halve dt [s] from ~``dt_start`` [s] until the displacement is within ``target_m`` [m] of
    ``reference_m`` [m] **and** stays within it at the next halving (Karnopp convergence is erratic).

    ``reference_m`` defaults to the package's converged answer, ``Simulator(contact, mode="event",
    dt=1e-6)``. ``kw`` (freq, stroke, x0, wavelength) go to :func:`reference_firing`. The first step
    is ``T/ceil(T/dt_start)`` and each next one exactly half the previous (n doubles). The search
    stops before a step below ``dt_min`` or a run predicted (2.2x the previous wall time) to overrun
    ``time_budget_s`` (counted from the call, including the reference run).

    Returns ``converged``, ``dt_s``, ``displacement_m``, ``error_m`` and ``wall_time_s`` of the
    chosen step (if not converged: the tried step with the smallest error), ``reference_m``,
    ``target_m``, ``tried`` (one dict per step: ``dt_s``, ``displacement_m``, ``error_m``,
    ``wall_time_s``), ``search_wall_s`` and ``stopped_by`` (why the search ended).
    """
    t_start = time.perf_counter()
    if reference_m is None:
        pkw = {k: kw[k] for k in ("freq", "stroke", "x0", "wavelength") if k in kw}
        reference_m = package_displacement(contact, dt=1e-6, mode="event", **pkw).displacement_m
    reference_m = float(reference_m)
    tables = _table_lists(contact)
    freq = float(kw.get("freq", 950.0))
    T = 1.0 / freq
    dt = T / max(int(math.ceil(T / dt_start - 1e-9)), 1)
    tried: list[tuple[float, float, float, float]] = []
    chosen: tuple[float, float, float, float] | None = None
    stopped_by: str | None = None
    last_wall = 0.0
    while True:
        if tried and dt < dt_min:
            stopped_by = f"dt_min ({dt_min:g} s)"
            break
        elapsed = time.perf_counter() - t_start
        if tried and elapsed + 2.2 * last_wall > time_budget_s:
            stopped_by = f"time budget ({time_budget_s:g} s)"
            break
        r = reference_firing(contact, dt=dt, _tables=tables, **kw)
        err = r["displacement_m"] - reference_m
        tried.append((r["dt_s"], r["displacement_m"], err, r["wall_time_s"]))
        last_wall = r["wall_time_s"]
        if len(tried) >= 2 and abs(tried[-2][2]) <= target_m and abs(err) <= target_m:
            chosen = tried[-2]
            stopped_by = "converged"
            break
        dt = r["dt_s"] / 2.0
    converged = chosen is not None
    if not converged:
        chosen = min(tried, key=lambda e: abs(e[2]))
    assert chosen is not None
    keys = ("dt_s", "displacement_m", "error_m", "wall_time_s")
    return {"converged": converged, **dict(zip(keys, chosen, strict=True)), "reference_m": reference_m,
            "target_m": target_m, "tried": [dict(zip(keys, row, strict=True)) for row in tried],
            "search_wall_s": time.perf_counter() - t_start, "stopped_by": stopped_by}


if __name__ == "__main__":
    from microconveyor_env.presets import load_preset

    print(json.dumps(converged_dt(load_preset("feasibility").contact), indent=2))
