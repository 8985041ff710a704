"""The firing map: one stroke's outcome as a fast function, tabulated once from the full model.

A planner asks one question thousands of times per decision: where does the part go if this
actuator fires now at frequency f with stroke h? On a flat, still surface the answer depends on
the part's **offset** to the actuator u = x − x_act [m] and its **velocity** v [m/s] when the
stroke starts, on f [Hz] and on h [m] (the surface is the same under every actuator, so the
position itself does not enter). The delay before a stroke and the coast after it are closed form
(:func:`.dynamics_kernel.coast`); only the stroke needs the integrator. The map tabulates the
stroke's end, ``(Δx, v_end)`` and whether the part stayed on the surface, on a regular grid over
(u, v, log f, h), every node fired once on the full compiled model (:func:`.batch.simulate_batch`,
the same kernel the envs step), and answers between nodes by multilinear interpolation
(compiled, well under a microsecond per query).

Trust. A query is **trusted** when every node of its grid cell ended the stroke on the surface;
the cells that touch a detachment (the edge of the usable frequency window, where the outcome
jumps) are not, and a planner either refuses them or fires them on the full model. Off the
grid's offset or velocity range a query is not trusted either. The error of trusted queries
against the full model is measured on states the map was not built from (:meth:`FiringMap.verify`):
the displacement error [m], and how many trusted queries detach on the full model (none, for the
scenes' maps: ``tests/physics/test_firing_map.py``).

The map is one material set, shape, wavelength, kinematics level, integrator and step (those of the
simulator it was built from) with the simulator's friction and mass (factors 1): a model part
with other factors is the full model's job.
"""
from __future__ import annotations

import functools
import hashlib
import math
import os
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Self

import numpy as np
from numba import njit, prange

from . import dynamics_kernel as kernel
from ..jit_cache import refresh as refresh_jit_cache
from .batch import simulate_batch
from .materials import ParameterError
from .simulator import Simulator
from .table_cache import cache_dir

MAP_FORMAT = 1   # bump when the stored layout changes


RELATIVE_FROM_M = 100e-6   # relative errors are quoted for displacements of at least this [m]


@dataclass(frozen=True)
class MapGrid:
    """The map's nodes: ``offset_m`` (lo [m], hi [m], nodes), ``velocity_m_s`` (lo [m/s], hi
    [m/s], nodes; one node at 0 for firings from rest), ``frequency_hz`` (lo [Hz], hi [Hz],
    nodes, evenly spaced in log f), ``stroke_m`` (lo [m], hi [m], nodes). Nodes are evenly
    spaced; an axis of one node takes only that value."""

    offset_m: tuple[float, float, int]
    velocity_m_s: tuple[float, float, int]
    frequency_hz: tuple[float, float, int]
    stroke_m: tuple[float, float, int]

    def __post_init__(self) -> None:
        for name in ("offset_m", "velocity_m_s", "frequency_hz", "stroke_m"):
            lo, hi, n = getattr(self, name)
            if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
                raise ParameterError(f"MapGrid.{name} nodes = {n!r} is invalid: must be an "
                                     "integer >= 1")
            if not (math.isfinite(lo) and math.isfinite(hi)) or hi < lo or (n > 1 and hi == lo) \
                    or (n == 1 and hi != lo):
                raise ParameterError(f"MapGrid.{name} = {(lo, hi, n)!r} is invalid: need lo < hi "
                                     "with >= 2 nodes, or lo == hi with one node")
        if self.frequency_hz[0] <= 0.0 or self.stroke_m[0] < 0.0:
            raise ParameterError("MapGrid: frequencies must be > 0 Hz and strokes >= 0 m")

    @property
    def shape(self) -> tuple[int, int, int, int]:
        return (self.offset_m[2], self.velocity_m_s[2], self.frequency_hz[2], self.stroke_m[2])

    def nodes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Each axis's node values (SI; frequencies in Hz)."""
        u = np.linspace(*self.offset_m)
        v = np.linspace(*self.velocity_m_s)
        lo, hi, n = self.frequency_hz
        f = np.exp(np.linspace(math.log(lo), math.log(hi), n))
        h = np.linspace(*self.stroke_m)
        return u, v, f, h

    def axes(self) -> np.ndarray:
        """``(4, 3)`` float array of (first node, step, nodes) per axis, the frequency in log f
        (what the compiled lookup reads)."""
        rows = []
        for lo, hi, n in (self.offset_m, self.velocity_m_s,
                          (math.log(self.frequency_hz[0]), math.log(self.frequency_hz[1]),
                           self.frequency_hz[2]), self.stroke_m):
            rows.append((lo, (hi - lo) / (n - 1) if n > 1 else 1.0, n))
        return np.array(rows, dtype=float)


@njit(cache=True)
def _locate(q: float, lo: float, step: float, n: float) -> tuple[int, float, bool]:
    """(cell index, weight of its upper node, inside the axis) of ``q`` on a uniform axis."""
    if n < 2.0:
        return 0, 0.0, q == lo
    s = (q - lo) / step
    last = n - 1.0
    if not (0.0 <= s <= last):   # also False for NaN
        return 0, 0.0, False
    i = min(int(s), int(last) - 1)
    return i, s - i, True


@njit(cache=True)
def _lookup_one(u: float, v: float, f: float, h: float, ax: np.ndarray, dx: np.ndarray,
                ve: np.ndarray, ok: np.ndarray) -> tuple[float, float, bool]:
    """(Δx [m], v_end [m/s], trusted) of one stroke by multilinear interpolation."""
    i0, w0, in0 = _locate(u, ax[0, 0], ax[0, 1], ax[0, 2])
    i1, w1, in1 = _locate(v, ax[1, 0], ax[1, 1], ax[1, 2])
    i2, w2, in2 = _locate(math.log(f), ax[2, 0], ax[2, 1], ax[2, 2])
    i3, w3, in3 = _locate(h, ax[3, 0], ax[3, 1], ax[3, 2])
    if not (in0 and in1 and in2 and in3):
        return math.nan, math.nan, False
    n1, n3 = ax[1, 2] > 1.0, ax[3, 2] > 1.0
    x_acc = 0.0
    v_acc = 0.0
    trusted = True
    for a in range(2):
        wa = w0 if a else 1.0 - w0
        for b in range(2 if n1 else 1):
            wb = (w1 if b else 1.0 - w1) if n1 else 1.0
            for c in range(2):
                wc = w2 if c else 1.0 - w2
                for d in range(2 if n3 else 1):
                    wd = (w3 if d else 1.0 - w3) if n3 else 1.0
                    j0, j1, j2, j3 = i0 + a, i1 + b, i2 + c, i3 + d
                    if not ok[j0, j1, j2, j3]:
                        trusted = False
                    w = wa * wb * wc * wd
                    x_acc += w * dx[j0, j1, j2, j3]
                    v_acc += w * ve[j0, j1, j2, j3]
    if not trusted:
        return math.nan, math.nan, False
    return x_acc, v_acc, True


@njit(cache=True, parallel=False)
def lookup(u: np.ndarray, v: np.ndarray, f: np.ndarray, h: np.ndarray, ax: np.ndarray,
           dx: np.ndarray, ve: np.ndarray, ok: np.ndarray, out_dx: np.ndarray,
           out_v: np.ndarray, out_ok: np.ndarray) -> None:
    """Every stroke of the (equal-length) arrays: ``out_dx`` [m], ``out_v`` [m/s] (NaN where not
    trusted), ``out_ok``."""
    for i in range(u.shape[0]):
        x_, v_, t_ = _lookup_one(u[i], v[i], f[i], h[i], ax, dx, ve, ok)
        out_dx[i] = x_
        out_v[i] = v_
        out_ok[i] = t_


@njit(cache=True)
def rest_after(u: np.ndarray, v: np.ndarray, f: np.ndarray, h: np.ndarray, ax: np.ndarray,
               dx: np.ndarray, ve: np.ndarray, ok: np.ndarray, P: np.ndarray, tu: np.ndarray,
               tq: np.ndarray, tqu: np.ndarray, out_dx: np.ndarray, out_t: np.ndarray,
               out_ok: np.ndarray) -> None:
    """The stroke from the map, then the closed-form coast to rest on the still surface
    (:func:`.dynamics_kernel.coast`): where the part rests relative to where the stroke started
    [m] and how long after the stroke's start [s]; NaN and False where the map is not trusted."""
    for i in range(u.shape[0]):
        x_, v_, t_ = _lookup_one(u[i], v[i], f[i], h[i], ax, dx, ve, ok)
        if not t_:
            out_dx[i] = math.nan
            out_t[i] = math.nan
            out_ok[i] = False
            continue
        xr, vr, used, at_rest, t_stop = kernel.coast(x_, v_, math.inf, P, tu, tq, tqu)
        out_dx[i] = xr
        out_t[i] = 1.0 / f[i] + used
        out_ok[i] = at_rest


@njit(cache=True, parallel=True)
def _strokes(u: np.ndarray, v: np.ndarray, f: np.ndarray, h: np.ndarray, dt: float,
             min_steps: int, t_max: float, P: np.ndarray, tu: np.ndarray, tq: np.ndarray,
             tqu: np.ndarray, out: np.ndarray) -> None:
    """One stroke per row on the full model (actuator at 0, part at u with velocity v), no
    delay, not coasted to rest: ``out`` rows as :func:`.dynamics_kernel.run` fills them."""
    rec = np.zeros((0, kernel.N_REC))
    for i in prange(u.shape[0]):
        row = out[i]
        kernel.reset_out(row)
        x, w, t, code = kernel.fire(u[i], v[i], 0.0, 0.0, f[i], h[i], 0.0, dt, min_steps, False,
                                    t_max, P, tu, tq, tqu, rec, row)
        kernel.finish_out(row, x, w, t, code)


def full_strokes(sim: Simulator, u: np.ndarray, v: np.ndarray, f: np.ndarray,
                 h: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Strokes on the full model (the map's reference): ``(Δx [m], v_end [m/s], outcome code)``
    for a part at offset ``u`` [m] from the actuator with velocity ``v`` [m/s], fired at ``f``
    [Hz] with stroke ``h`` [m] (equal-length arrays), on as many threads as numba is set to."""
    arrs = [np.ascontiguousarray(np.asarray(a, float)) for a in (u, v, f, h)]
    sim.check_firings(np.array([arrs[2].max()]), np.array([arrs[3].max()]))
    out = np.zeros((len(arrs[0]), kernel.N_OUT))
    _strokes(*arrs, sim.dt, sim.min_steps, sim.max_time, sim.params, *sim.tables, out)  # type: ignore[call-arg, arg-type]
    return (out[:, kernel.O_X] - arrs[0], out[:, kernel.O_V],
            out[:, kernel.O_OUTCOME].astype(np.int64))


_MEMO: dict[str, FiringMap] = {}


@functools.lru_cache(maxsize=1)
def _code_hash() -> str:
    """Hash of the source the map's numbers come from: the kernel's modules and this one."""
    here = Path(__file__).parent
    h = hashlib.sha256()
    for name in ("dynamics_kernel", "forces", "events", "kinematics", "firing_map"):
        h.update((here / f"{name}.py").read_bytes())
    return h.hexdigest()[:16]


def hash_key(head: str, sim: Any, grid: MapGrid) -> str:
    """Hash of ``head`` (a map kind's format and source hash), ``sim``'s step settings,
    constants and tables, and ``grid``: a map's cache key."""
    h = hashlib.sha256()
    h.update(f"{head}|{sim.dt!r}|{sim.min_steps!r}|{sim.max_time!r}|{grid!r}".encode())
    for a in (sim.params, *sim.tables):
        h.update(np.ascontiguousarray(a, float).tobytes())
    return h.hexdigest()[:32]


def map_key(sim: Simulator, grid: MapGrid) -> str:
    """Hash of everything a map's numbers depend on (see :meth:`FiringMap.cached`)."""
    return hash_key(f"{MAP_FORMAT}|{_code_hash()}", sim, grid)


@dataclass
class MapError:
    """A map against the full model on held-out strokes (SI units): the trusted share; of the
    trusted strokes that stay on the surface on the full model, the displacement error's median,
    90th, 99th percentile and maximum [m], and the largest error relative to the full model's
    displacement [-] where that is at least :data:`RELATIVE_FROM_M`; trusted strokes that detach on the full model (misclassified); untrusted
    strokes that stay on the surface (where the planner must fire the full model); the wall time
    per query of the map and per stroke of the full model [s], one thread each."""

    samples: int
    trusted_share: float
    error_median_m: float
    error_p90_m: float
    error_p99_m: float
    error_max_m: float
    relative_error_max: float
    misclassified_detachments: int
    untrusted_on_surface_share: float
    map_query_s: float
    full_stroke_s: float
    to_rest: bool

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def summary(cls, err: np.ndarray, moved: np.ndarray, trusted: np.ndarray, on: np.ndarray,
                map_query_s: float, full_stroke_s: float, to_rest: bool,
                **extra: Any) -> Any:
        """The figures of held-out strokes: ``err`` [m] the map's error and ``moved`` [m] how
        far the full model moved the part, over the strokes the map trusts that stay on the
        surface (``trusted & on``); ``trusted`` and ``on`` over all of them; the timings [s];
        ``extra``: a subclass's fields."""
        big = moved >= RELATIVE_FROM_M
        rel = err[big] / moved[big]
        pct = np.percentile(err, [50, 90, 99, 100]) if err.size else np.full(4, np.nan)
        return cls(samples=len(trusted), trusted_share=float(trusted.mean()),
                   error_median_m=float(pct[0]), error_p90_m=float(pct[1]),
                   error_p99_m=float(pct[2]), error_max_m=float(pct[3]),
                   relative_error_max=float(rel.max()) if rel.size else math.nan,
                   misclassified_detachments=int((trusted & ~on).sum()),
                   untrusted_on_surface_share=float((~trusted & on).mean()),
                   map_query_s=map_query_s, full_stroke_s=full_stroke_s, to_rest=bool(to_rest),
                   **extra)


class FiringMap:
    """One stroke's outcome on a regular grid (module docstring); build with :meth:`build`."""

    def __init__(self, sim: Simulator, grid: MapGrid, dx: np.ndarray, v_end: np.ndarray,
                 ok: np.ndarray, build_s: float = math.nan) -> None:
        if dx.shape != grid.shape or v_end.shape != grid.shape or ok.shape != grid.shape:
            raise ParameterError(f"FiringMap: arrays of shape {dx.shape}, grid {grid.shape}")
        self.sim = sim
        self.grid = grid
        self.dx = np.ascontiguousarray(dx, float)
        self.v_end = np.ascontiguousarray(v_end, float)
        self.ok = np.ascontiguousarray(ok, np.bool_)
        self.ax = grid.axes()
        self.build_s = build_s

    @classmethod
    def build(cls, sim: Simulator, grid: MapGrid) -> FiringMap:
        """Fire every node of ``grid`` on ``sim``'s full model (its friction and mass)."""
        u, v, f, h = (a.ravel() for a in np.meshgrid(*grid.nodes(), indexing="ij"))
        t0 = time.perf_counter()
        dx, ve, code = full_strokes(sim, u, v, f, h)
        ok = code == kernel.MOVING   # the stroke ran to its end on the surface
        return cls(sim, grid, dx.reshape(grid.shape), ve.reshape(grid.shape),
                   ok.reshape(grid.shape), time.perf_counter() - t0)

    CACHE_NAME = "firing-map"   # the cache file's name: <CACHE_NAME>-<key>.npz

    @classmethod
    def _memo(cls) -> dict[str, Any]:
        """This process's maps of this kind, by key."""
        return _MEMO

    @classmethod
    def _key(cls, sim: Any, grid: MapGrid) -> str:
        return map_key(sim, grid)

    @classmethod
    def cached(cls, sim: Any, grid: MapGrid) -> Self:
        """The map of ``sim`` on ``grid``: from this process's memory, else from the cache folder
        (``<CACHE_NAME>-<key>.npz`` in :func:`.table_cache.cache_dir`, keyed by the simulator's
        constants and tables, its step settings, the grid and the source of the kernel and of
        the map's module), else built and stored there (atomically; an unwritable folder is not
        an error)."""
        key = cls._key(sim, grid)
        memo = cls._memo()
        hit = memo.get(key)
        if hit is not None:
            return hit
        path = cache_dir() / f"{cls.CACHE_NAME}-{key}.npz"
        made: Any = None   # this class's map (build is each kind's own)
        try:
            with np.load(path, allow_pickle=False) as z:
                if str(z["key"]) == key:
                    made = cls(sim, grid, z["dx"], z["v_end"], z["ok"], float(z["build_s"]))
        except (OSError, KeyError, ValueError, ParameterError):
            made = None
        if made is None:
            made = cls.build(sim, grid)
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".npz.tmp")
                with os.fdopen(fd, "wb") as fh:
                    np.savez(fh, key=key, dx=made.dx, v_end=made.v_end, ok=made.ok,
                             build_s=made.build_s)
                os.replace(tmp, path)
            except OSError:
                pass
        memo[key] = made
        return made

    @property
    def nodes(self) -> int:
        return int(np.prod(self.grid.shape))

    @staticmethod
    def _arrays(*qs: Any) -> list[np.ndarray]:
        arrs = np.broadcast_arrays(*[np.asarray(q, float) for q in qs])
        return [np.ascontiguousarray(a.ravel()) for a in arrs]

    def stroke(self, u: Any, v: Any, f: Any, h: Any
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(Δx [m], v_end [m/s], trusted)`` at the end of the stroke for a part at offset ``u``
        [m] with velocity ``v`` [m/s], fired at ``f`` [Hz] with stroke ``h`` [m] (arrays
        broadcast together; NaN where not trusted)."""
        a = self._arrays(u, v, f, h)
        n = len(a[0])
        out_dx, out_v, out_ok = np.empty(n), np.empty(n), np.empty(n, np.bool_)
        lookup(*a, self.ax, self.dx, self.v_end, self.ok, out_dx, out_v, out_ok)  # type: ignore[call-arg]
        return out_dx, out_v, out_ok

    def rest(self, u: Any, f: Any, h: Any, v: Any = 0.0
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(Δx [m], t [s], trusted)``: where the part comes to rest relative to where the
        stroke started, and when after the stroke's start, coasting on the still surface after
        the stroke (NaN where not trusted)."""
        a = self._arrays(u, v, f, h)
        n = len(a[0])
        out_dx, out_t, out_ok = np.empty(n), np.empty(n), np.empty(n, np.bool_)
        rest_after(*a, self.ax, self.dx, self.v_end, self.ok, self.sim.params,  # type: ignore[call-arg]
                   *self.sim.tables, out_dx, out_t, out_ok)
        return out_dx, out_t, out_ok

    def draw(self, n: int, seed: int) -> tuple[np.ndarray, ...]:
        """``n`` strokes drawn uniformly over the grid's box (log-uniform in f) with ``seed``:
        states the map was not built from (u, v, f, h)."""
        rng = np.random.default_rng(seed)
        g = self.grid
        u = rng.uniform(g.offset_m[0], g.offset_m[1], n)
        v = rng.uniform(g.velocity_m_s[0], g.velocity_m_s[1], n)
        f = np.exp(rng.uniform(math.log(g.frequency_hz[0]), math.log(g.frequency_hz[1]), n))
        h = rng.uniform(g.stroke_m[0], g.stroke_m[1], n)
        return u, v, f, h

    def verify(self, n: int = 20000, seed: int = 12345, to_rest: bool | None = None
               ) -> MapError:
        """The map against the full model on ``n`` held-out strokes (:meth:`draw` with
        ``seed``). ``to_rest`` compares where the part comes to rest after the stroke (default
        when the map holds firings from rest only), else the stroke's end."""
        u, v, f, h = self.draw(n, seed)
        self.stroke(u[:1], v[:1], f[:1], h[:1])          # compiled before the clock starts
        self.rest(u[:1], f[:1], h[:1], v[:1])
        simulate_batch(self.sim, np.zeros((1, 1)), f[:1, None], h[:1, None], 0.0, u[:1], v[:1],
                       parallel=False)
        if to_rest is None:
            to_rest = self.grid.velocity_m_s[2] == 1
        t0 = time.perf_counter()
        if to_rest:
            pred, _, trusted = self.rest(u, f, h, v)
        else:
            pred, _, trusted = self.stroke(u, v, f, h)
        t_map = (time.perf_counter() - t0) / n
        xa = np.zeros((n, 1))
        t0 = time.perf_counter()
        r = simulate_batch(self.sim, xa, f[:, None], h[:, None], 0.0, u, v, parallel=False,
                           to_rest=to_rest)
        t_full = (time.perf_counter() - t0) / n
        true = r.final_position_m - u
        on = r.code != kernel.DETACHED
        on &= np.isin(r.code, (kernel.REST, kernel.MOVING))
        good = trusted & on
        error: MapError = MapError.summary(np.abs(pred[good] - true[good]), np.abs(true[good]),
                                           trusted, on, t_map, t_full, to_rest)
        return error


refresh_jit_cache(globals())
