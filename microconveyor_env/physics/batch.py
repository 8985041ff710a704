"""Many whole schedules through one compiled call: the batched counterpart of
:meth:`.simulator.Simulator.simulate` (no trajectories).

Row ``b`` of the ``(B, n)`` arrays is one run: firing ``k`` of actuator ``xa[b, k]`` [m] at
frequency ``f[b, k]`` [Hz] with stroke ``h[b, k]`` [m] after ``delay[b, k]`` [s] (from the end of
the previous stroke; from t = 0 for the first), starting from ``x0[b]`` [m] at ``v0[b]`` [m/s].
Each row runs exactly as ``Simulator.simulate`` runs it (the same compiled :func:`.dynamics_kernel.run`),
so the results are bit-identical to the one-at-a-time calls, serial or parallel. Unlike the env,
every row may have its own actuator positions (e.g. a different spacing per optimiser candidate).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from numba import njit, prange

from . import dynamics_kernel as kernel
from .contact_table import TableRangeError
from ..jit_cache import refresh as refresh_jit_cache
from .materials import ParameterError
from .simulator import Simulator, stroke_steps

_NO_RECORD = np.zeros((0, kernel.N_REC))


Arr = np.ndarray


@njit(cache=True)
def _run_row(i: int, xa: Arr, f: Arr, h: Arr, d: Arr, x0: Arr, v0: Arr, dt: float,
             min_steps: int, to_rest: bool, t_max: float, P: Arr, tu: Arr, tq: Arr, tqu: Arr,
             rec: Arr, out: Arr) -> None:
    kernel.run(xa[i], f[i], h[i], d[i], x0[i], v0[i], 0.0, dt, min_steps, to_rest, t_max, P, tu,
               tq, tqu, rec, out[i])


@njit(cache=True)
def run_serial(xa: Arr, f: Arr, h: Arr, d: Arr, x0: Arr, v0: Arr, dt: float, min_steps: int,
               to_rest: bool, t_max: float, P: Arr, tu: Arr, tq: Arr, tqu: Arr, rec: Arr,
               out: Arr) -> None:
    """Every row of the batch, one after the other; ``out`` is ``(B, N_OUT)``."""
    for i in range(xa.shape[0]):
        _run_row(i, xa, f, h, d, x0, v0, dt, min_steps, to_rest, t_max, P, tu, tq, tqu, rec, out)


@njit(cache=True, parallel=True)
def run_parallel(xa: Arr, f: Arr, h: Arr, d: Arr, x0: Arr, v0: Arr, dt: float, min_steps: int,
                 to_rest: bool, t_max: float, P: Arr, tu: Arr, tq: Arr, tqu: Arr, rec: Arr,
                 out: Arr) -> None:
    """Every row of the batch in numba's parallel loop (as many threads as numba is set to)."""
    for i in prange(xa.shape[0]):
        _run_row(i, xa, f, h, d, x0, v0, dt, min_steps, to_rest, t_max, P, tu, tq, tqu, rec, out)


@dataclass
class BatchResult:
    """Outcomes of a batch (arrays over the rows, SI units).

    ``outcome`` holds the names of :data:`.dynamics_kernel.OUTCOMES` (``rest``, ``detached``,
    ``max_time``, ``moving``, ``too_many_events``); ``end_time_s`` is the rest time for ``rest``,
    the detachment time for ``detached``; ``event_position_m`` is where the part detached (NaN
    otherwise)."""

    final_position_m: np.ndarray
    final_velocity_m_s: np.ndarray
    end_time_s: np.ndarray
    outcome: np.ndarray
    event_position_m: np.ndarray
    steps: np.ndarray
    wall_time_s: float

    @property
    def code(self) -> np.ndarray:
        """Outcome codes (:data:`.dynamics_kernel.REST`, ``DETACHED``, ...)."""
        return np.array([kernel.OUTCOMES.index(o) for o in self.outcome], dtype=np.int64)


def _rows(name: str, a: npt.ArrayLike, shape: tuple[int, int], lo: float, hi: float,
          lo_open: bool = False) -> np.ndarray:
    arr = np.ascontiguousarray(np.broadcast_to(np.asarray(a, dtype=float), shape))
    bad = ~np.isfinite(arr) | (arr > hi) | ((arr <= lo) if lo_open else (arr < lo))
    if bad.any():
        i = tuple(int(v) for v in np.argwhere(bad)[0])
        raise ParameterError(f"simulate_batch: {name}{list(i)} = {arr[i]!r} is invalid: must be "
                             f"in {'(' if lo_open else '['}{lo:g}, {hi:g}]")
    return arr


def simulate_batch(sim: Simulator, xa: npt.ArrayLike, f: npt.ArrayLike, h: npt.ArrayLike,
                   delay: npt.ArrayLike, x0: npt.ArrayLike, v0: npt.ArrayLike = 0.0,
                   parallel: bool = True, to_rest: bool = True) -> BatchResult:
    """Run a batch of schedules on ``sim``'s model (see the module docstring).

    ``xa`` actuator positions [m], ``f`` frequencies [Hz], ``h`` strokes [m], ``delay`` [s]:
    ``(B, n)`` arrays (anything broadcasting to the shape of ``xa``); ``x0`` [m], ``v0`` [m/s]:
    per row or scalars. ``parallel``: numba's parallel loop (threads as set by the caller, e.g.
    ``numba.set_num_threads``) or a serial loop; the results are identical. ``to_rest``: after
    the last firing, coast to rest (else stop at the end of the last stroke, outcome ``moving``).
    The checks of :meth:`Simulator.check_firings` apply to every row (step budget per row).
    """
    xa_arr = np.asarray(xa, dtype=float)
    if xa_arr.ndim != 2 or xa_arr.shape[1] < 1 or xa_arr.shape[0] < 1:
        raise ParameterError(f"simulate_batch: xa must be a (runs, firings) array, got shape "
                             f"{xa_arr.shape}")
    shape = (int(xa_arr.shape[0]), int(xa_arr.shape[1]))
    xa_arr = _rows("xa", xa_arr, shape, -1.0, 1.0)
    fa = _rows("f", f, shape, 0.0, 1e6, lo_open=True)
    ha = _rows("h", h, shape, 0.0, 1e-2)
    da = _rows("delay", delay, shape, 0.0, 1e4)
    x0a = _rows("x0", np.asarray(x0, dtype=float).reshape(-1, 1), (shape[0], 1), -1.0, 1.0)[:, 0]
    v0a = _rows("v0", np.asarray(v0, dtype=float).reshape(-1, 1), (shape[0], 1), -100.0,
                100.0)[:, 0]
    # the simulator's checks on the rows that decide them: the most RK4 steps, the fastest
    # stroke (resolution warning), the largest peak load, the largest stroke (stretch tables)
    steps = stroke_steps(fa, sim.dt, sim.min_steps).sum(axis=1)
    rows = {int(np.argmax(steps)), int(np.argmax(fa.max(1))), int(np.argmax((ha * fa ** 2).max(1))),
            int(np.argmax(ha.max(1)))}
    for r in sorted(rows):
        sim.check_firings(fa[r], ha[r])
    out = np.zeros((shape[0], kernel.N_OUT))
    t0 = time.perf_counter()
    fn = run_parallel if parallel and shape[0] > 1 else run_serial
    fn(xa_arr, fa, ha, da, np.ascontiguousarray(x0a), np.ascontiguousarray(v0a),  # type: ignore[call-arg]
       sim.dt, sim.min_steps, to_rest, sim.max_time, sim.params, *sim.tables, _NO_RECORD, out)
    wall = time.perf_counter() - t0
    codes = out[:, kernel.O_OUTCOME].astype(np.int64)
    if (codes == kernel.BEYOND_TABLE).any():
        i = int(np.argmax(codes == kernel.BEYOND_TABLE))
        raise TableRangeError(f"the normal load exceeded the contact table "
                              f"({sim.table.max_load:.3g} N) in run {i} at t = "
                              f"{out[i, kernel.O_EVENT_T]:.6g} s; rebuild it with a larger "
                              "load_ratio")
    detached = codes == kernel.DETACHED
    return BatchResult(
        final_position_m=out[:, kernel.O_X].copy(), final_velocity_m_s=out[:, kernel.O_V].copy(),
        end_time_s=out[:, kernel.O_T].copy(),
        outcome=np.array(kernel.OUTCOMES, dtype=object)[codes],
        event_position_m=np.where(detached, out[:, kernel.O_EVENT_X], np.nan),
        steps=out[:, kernel.O_STEPS].astype(np.int64), wall_time_s=wall)


refresh_jit_cache(globals())
