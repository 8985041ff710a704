"""The plane's firing map from rest: where a resting part comes to rest after one actuator fires,
tabulated once on the plane's full model (:func:`.kernel.fire`) and interpolated.

On the level, still plane a radial bump (docs/physics.md §10.1) pushes a resting part along the
line through the actuator: the part breaks away along the gradient, which is radial, and nothing
turns it off that line (the surface is isotropic, the friction opposes the velocity). So the
outcome of a firing from rest depends only on the part's **radial offset** r = |p − p_act| [m],
the frequency f [Hz] and the stroke h [m], not on the direction: the part ends at
``p + Δr · e`` with ``e = (p − p_act)/r`` (Δr < 0: towards the actuator, or past it). The map
tabulates the stroke's end (Δr, the radial velocity) on a grid over (r, log f, h), every node
fired from rest at ``(r, 0)`` next to an actuator at the origin on the full compiled model,
answers between nodes by multilinear interpolation (:class:`..firing_map.FiringMap`, whose grid,
lookup and trust mask it reuses: a query is trusted when every node of its cell stayed on the
surface), and coasts the part to rest in closed form (:func:`.kernel.coast`).

Its error against the full model is measured on held-out firings from rest in every direction
(:meth:`PlaneFiringMap.verify`): the distance between the predicted and the simulated rest
[m], the displacement perpendicular to the line through the actuator (0 to rounding: the radial
symmetry), and how many trusted firings detach on the full model (none:
``tests/physics/test_plane_firing_map.py``).

The map is one material set, shape, wavelength, kinematics level, step and time limit (those of
the simulator it was built from) with the simulator's friction and mass (factors 1); a model
part with other factors is the full model's job.
"""
from __future__ import annotations

import functools
import hashlib
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit, prange

from ...jit_cache import refresh as refresh_jit_cache
from .. import dynamics_kernel as kernel1d
from ..firing_map import FiringMap, MapError, MapGrid, hash_key, lookup
from ..materials import ParameterError
from . import kernel
from .simulator import PlaneSimulator

PLANE_MAP_FORMAT = 1   # bump when the stored layout changes


@njit(cache=True, parallel=True)
def _strokes(r, f, h, dt, min_steps, t_max, P, tu, tq, tqu, out):  # pragma: no cover - compiled
    """One stroke per row on the full model from rest at ``(r, 0)``, the actuator at the
    origin, no delay, not coasted to rest: ``out`` rows as :func:`.kernel.run` fills them."""
    rec = np.zeros((0, kernel.N_REC))
    for i in prange(r.shape[0]):
        row = out[i]
        kernel.reset_out(row)
        x, y, vx, vy, t, code = kernel.fire(r[i], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, f[i], h[i], 0.0,
                                            dt, min_steps, False, t_max, P, tu, tq, tqu, rec, row)
        kernel.finish_out(row, x, y, vx, vy, t, code)


@njit(cache=True)
def _firings(px, py, ax, ay, f, h, dt, min_steps, t_max, P, tu, tq, tqu, out):  # pragma: no cover
    """One firing per row on the full model from rest at ``(px, py)`` by the actuator at
    ``(ax, ay)``, no delay, coasted to rest, one thread: ``out`` rows as :func:`.kernel.run`
    fills them."""
    rec = np.zeros((0, kernel.N_REC))
    for i in range(px.shape[0]):
        row = out[i]
        kernel.reset_out(row)
        x, y, vx, vy, t, code = kernel.fire(px[i], py[i], 0.0, 0.0, 0.0, ax[i], ay[i], f[i],
                                            h[i], 0.0, dt, min_steps, True, t_max, P, tu, tq, tqu,
                                            rec, row)
        kernel.finish_out(row, x, y, vx, vy, t, code)


@njit(cache=True)
def _coast_rest(px, py, ex, ey, dr, vr, f, P, tu, tq, tqu, out_x, out_y, out_t,
                out_ok):  # pragma: no cover - compiled
    """The stroke's end ``p + dr e`` with velocity ``vr e`` coasted to rest on the still plane
    (:func:`.kernel.coast`): the rest [m], its time after the stroke's start [s], whether it
    rests (False where ``dr`` is NaN: the map did not trust the stroke)."""
    for i in range(px.shape[0]):
        if not (dr[i] == dr[i]):
            out_x[i] = out_y[i] = out_t[i] = math.nan
            out_ok[i] = False
            continue
        x, y, _, _, used, rest, _ = kernel.coast(px[i] + dr[i] * ex[i], py[i] + dr[i] * ey[i],
                                                 vr[i] * ex[i], vr[i] * ey[i], math.inf, P, tu,
                                                 tq, tqu)
        out_x[i] = x
        out_y[i] = y
        out_t[i] = 1.0 / f[i] + used
        out_ok[i] = rest


def full_strokes(sim: PlaneSimulator, r: np.ndarray, f: np.ndarray,
                 h: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Strokes from rest on the full plane model (the map's reference) for a part at radial
    offset ``r`` [m] from the actuator, fired at ``f`` [Hz] with stroke ``h`` [m] (equal-length
    arrays), on as many threads as numba is set to: ``(Δr [m], v_r [m/s], Δ⊥ [m], outcome
    code)`` at the stroke's end, Δ⊥ the displacement off the line through the actuator."""
    arrs = [np.ascontiguousarray(np.asarray(a, float)) for a in (r, f, h)]
    sim.check_firings(np.array([arrs[1].max()]), np.array([arrs[2].max()]))
    out = np.zeros((len(arrs[0]), kernel.N_OUT))
    _strokes(*arrs, sim.dt, sim.min_steps, sim.max_time, sim.params, *sim.tables, out)  # type: ignore[call-arg]
    return (out[:, kernel.O_X] - arrs[0], out[:, kernel.O_VX], out[:, kernel.O_Y],
            out[:, kernel.O_OUTCOME].astype(np.int64))


def full_firings(sim: PlaneSimulator, p: np.ndarray, a: np.ndarray, f: np.ndarray,
                 h: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Firings from rest on the full plane model, coasted to rest, one thread: a part resting
    at ``p`` ``(n, 2)`` [m], the actuator at ``a`` ``(n, 2)`` [m], ``f`` [Hz], ``h`` [m].
    Returns the end ``(n, 2)`` [m], its time [s] and the outcome code."""
    p, a = (np.asarray(v, float).reshape(-1, 2) for v in (p, a))
    f, h = (np.ascontiguousarray(np.asarray(v, float)) for v in (f, h))
    out = np.zeros((len(p), kernel.N_OUT))
    _firings(*(np.ascontiguousarray(c) for c in (p[:, 0], p[:, 1], a[:, 0], a[:, 1])), f, h,  # type: ignore[call-arg]
             sim.dt, sim.min_steps, sim.max_time, sim.params, *sim.tables, out)
    return (out[:, [kernel.O_X, kernel.O_Y]], out[:, kernel.O_T],
            out[:, kernel.O_OUTCOME].astype(np.int64))


@dataclass
class PlaneMapError(MapError):
    """:class:`..firing_map.MapError` of the plane's map (the errors are distances between the
    predicted and the simulated rest [m]; relative to the distance travelled), with the largest
    displacement off the line through the actuator on the full model ``perpendicular_max_m``
    [m] (0 to rounding on the isotropic plane) and the direction-independence of the full
    model, ``rotation_max_m`` [m]: the largest distance between a firing's rest and that of the
    same firing turned onto the x axis."""

    perpendicular_max_m: float = math.nan
    rotation_max_m: float = math.nan


_MEMO: dict[str, PlaneFiringMap] = {}


@functools.lru_cache(maxsize=1)
def _code_hash() -> str:
    """Hash of the source the map's numbers come from: the plane kernel's modules, the 1-D
    forces and contact they call, the shared map and this module."""
    here = Path(__file__).parent
    h = hashlib.sha256()
    for path in sorted(here.glob("*.py")) + [here.parent / f"{n}.py" for n in
                                             ("dynamics_kernel", "forces", "events", "kinematics",
                                              "firing_map")]:
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def map_key(sim: PlaneSimulator, grid: MapGrid) -> str:
    """Hash of everything a plane map's numbers depend on (see :meth:`PlaneFiringMap.cached`)."""
    return hash_key(f"plane|{PLANE_MAP_FORMAT}|{_code_hash()}", sim, grid)


def check_radial(grid: MapGrid) -> None:
    """A plane map's grid: radial offsets from 0 up, one velocity node at 0 (from rest)."""
    if grid.offset_m[0] < 0.0 or grid.velocity_m_s != (0.0, 0.0, 1):
        raise ParameterError(f"a plane firing map tabulates firings from rest over radial "
                             f"offsets >= 0: got offset_m = {grid.offset_m!r}, velocity_m_s = "
                             f"{grid.velocity_m_s!r} (need lo >= 0 and (0.0, 0.0, 1))")


class PlaneFiringMap(FiringMap):
    """A firing from rest on the plane (module docstring); build with :meth:`build` or
    :meth:`cached`. The grid's offset axis is the radial offset [m] (from 0 up) and its
    velocity axis the single node 0; :meth:`stroke` and :meth:`rest` of
    :class:`..firing_map.FiringMap` answer in that radial offset (``sim`` there is the plane's
    1-D simulator: the same constants and table); :meth:`rest_at` answers in the plane."""

    def __init__(self, sim: PlaneSimulator, grid: MapGrid, dx: np.ndarray, v_end: np.ndarray,
                 ok: np.ndarray, build_s: float = math.nan) -> None:
        check_radial(grid)
        super().__init__(sim.line, grid, dx, v_end, ok, build_s)
        self.plane = sim

    @classmethod
    def build(cls, sim: Any, grid: MapGrid) -> PlaneFiringMap:
        """Fire every node of ``grid`` from rest on ``sim``'s full plane model (its friction
        and mass)."""
        check_radial(grid)
        r, _, f, h = (a.ravel() for a in np.meshgrid(*grid.nodes(), indexing="ij"))
        t0 = time.perf_counter()
        dr, vr, _, code = full_strokes(sim, r, f, h)
        ok = code == kernel1d.MOVING   # the stroke ran to its end on the surface
        return cls(sim, grid, dr.reshape(grid.shape), vr.reshape(grid.shape),
                   ok.reshape(grid.shape), time.perf_counter() - t0)

    CACHE_NAME = "plane-firing-map"

    @classmethod
    def _memo(cls) -> dict[str, Any]:
        return _MEMO

    @classmethod
    def _key(cls, sim: Any, grid: MapGrid) -> str:
        return map_key(sim, grid)

    def rest_at(self, part: Any, actuator: Any, f: Any, h: Any
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Where a part resting at ``part`` ``(n, 2)`` [m] (or one ``(2,)`` for all) comes to
        rest when the actuator at ``actuator`` ``(n, 2)`` [m] fires at ``f`` [Hz] with stroke
        ``h`` [m] (arrays of n or scalars): the rest ``(n, 2)`` [m], its time after the stroke's
        start [s] and whether the map trusts it (NaN where not). A part on the actuator's
        centre stays (the slope under it is 0)."""
        pa = np.asarray(part, float).reshape(-1, 2)
        aa = np.asarray(actuator, float).reshape(-1, 2)
        n = max(len(pa), len(aa), np.size(f), np.size(h))

        def column(a: Any) -> np.ndarray:   # writable, contiguous float64 of n (one type)
            return np.array(np.broadcast_to(np.asarray(a, float), (n,)), dtype=float)

        px, py = column(pa[:, 0] if len(pa) > 1 else pa[0, 0]), \
            column(pa[:, 1] if len(pa) > 1 else pa[0, 1])
        dx = px - column(aa[:, 0] if len(aa) > 1 else aa[0, 0])
        dy = py - column(aa[:, 1] if len(aa) > 1 else aa[0, 1])
        r = np.hypot(dx, dy)
        safe = np.where(r > 0.0, r, 1.0)
        ex, ey = dx / safe, dy / safe
        ff, hh, v0 = column(f), column(h), np.zeros(n)
        dr, vr, ok = np.empty(n), np.empty(n), np.empty(n, np.bool_)
        lookup(r, v0, ff, hh, self.ax, self.dx, self.v_end, self.ok, dr, vr, ok)
        out_x, out_y, out_t, out_ok = np.empty(n), np.empty(n), np.empty(n), np.empty(n, np.bool_)
        _coast_rest(px, py, ex, ey, dr, vr, ff, self.sim.params, *self.sim.tables,  # type: ignore[call-arg]
                    out_x, out_y, out_t, out_ok)
        return np.stack([out_x, out_y], 1), out_t, out_ok

    def draw_plane(self, n: int, seed: int) -> tuple[np.ndarray, ...]:
        """``n`` firings from rest drawn with ``seed``: a part at radial offset ``r`` uniform
        over the grid's offsets, in a direction ``theta`` uniform in [0, 2 pi) [rad], from an
        actuator at the origin; ``f`` log-uniform, ``h`` uniform over the grid's ranges."""
        rng = np.random.default_rng(seed)
        g = self.grid
        r = rng.uniform(g.offset_m[0], g.offset_m[1], n)
        theta = rng.uniform(0.0, 2.0 * math.pi, n)
        f = np.exp(rng.uniform(math.log(g.frequency_hz[0]), math.log(g.frequency_hz[1]), n))
        h = rng.uniform(g.stroke_m[0], g.stroke_m[1], n)
        return r, theta, f, h

    def verify(self, n: int = 20000, seed: int = 12345, to_rest: bool | None = None
               ) -> PlaneMapError:
        """The map against the full plane model on ``n`` held-out firings from rest in every
        direction (:meth:`draw_plane` with ``seed``), each coasted to rest (``to_rest`` must be
        None or True): the distance between the predicted and the simulated rest, the
        perpendicular displacement on the full model and the difference from the same firing
        turned onto the x axis (:class:`PlaneMapError`; timings one thread each)."""
        if to_rest is False:
            raise ParameterError("the plane's map is checked where the part comes to rest")
        r, theta, f, h = self.draw_plane(n, seed)
        e = np.stack([np.cos(theta), np.sin(theta)], 1)
        part = r[:, None] * e
        zero = np.zeros((n, 2))
        self.rest_at(part[:1], zero[:1], f[:1], h[:1])       # compiled before the clock starts
        full_firings(self.plane, part[:1], zero[:1], f[:1], h[:1])
        t0 = time.perf_counter()
        pred, _, trusted = self.rest_at(part, zero, f, h)
        t_map = (time.perf_counter() - t0) / n
        t0 = time.perf_counter()
        true, _, code = full_firings(self.plane, part, zero, f, h)
        t_full = (time.perf_counter() - t0) / n
        axis, _, code_axis = full_firings(self.plane, np.stack([r, np.zeros(n)], 1), zero, f, h)
        on = code == kernel1d.REST
        same = on & (code_axis == kernel1d.REST)
        rot = np.hypot(true[same, 0] - axis[same, 0] * e[same, 0],
                       true[same, 1] - axis[same, 0] * e[same, 1])
        perp = np.abs(true[on, 1] * e[on, 0] - true[on, 0] * e[on, 1])
        good = trusted & on
        error: PlaneMapError = PlaneMapError.summary(
            np.hypot(*(pred[good] - true[good]).T), np.hypot(*(true[good] - part[good]).T),
            trusted, on, t_map, t_full, True,
            perpendicular_max_m=float(perp.max()) if perp.size else math.nan,
            rotation_max_m=float(rot.max()) if rot.size else math.nan)
        return error


refresh_jit_cache(globals())
