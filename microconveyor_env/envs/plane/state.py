"""N parts on the plane: the state and the step that the single plane env (N = 1) and its batched
env share (arrays in :mod:`.step`, one compiled call per step through the container every scene
shares, :class:`~..core.parts.PartsBase`: serial or numba's parallel loop as
:class:`~..core.threads.ThreadChooser` picks; results bit-identical either way), the reset of one
part (a drawn or given target; with randomisation on, its factors and execution noise from the
streams derived from the part's generator, :mod:`..core.randomisation`; or a saved
:class:`~.part_state.PlaneState`) and its saved state."""
from __future__ import annotations

from typing import Any

import numpy as np

from ...physics.plane import kernel as plane_kernel
from ...physics.plane.simulator import PlaneSimulator
from ...presets import load_preset
from ..core import actions, randomisation
from . import task as plane_task
from .config import PlaneEnvConfig
from .step import (
    NO_NOISE,
    NO_RECORD,
    PlaneConstants,
    PlaneOutputs,
    PlaneParts,
    observe_all,
    step_parallel,
    step_serial,
)
from ..core.parts import PartsBase, check_table_reach, for_part
from ..core.versions import scene_of
from .part_state import PlaneState, check_plane_state


def make_plane_simulator(cfg: PlaneEnvConfig) -> PlaneSimulator:
    """The env's plane simulator; refuses action ranges whose strongest stroke would load the
    part (the heaviest ``mass_factor_range`` allows) beyond the contact table (checked once
    here, so steps never need to)."""
    sim = PlaneSimulator(load_preset(cfg.preset).contact, shape=cfg.shape,
                         wavelength=cfg.wavelength, kinematics=cfg.kinematics, dt=cfg.dt,
                         max_time=cfg.max_time, min_steps=cfg.min_steps, max_steps=cfg.max_steps)
    check_table_reach(sim, cfg)
    return sim


def check_plane_target(target: object) -> tuple[float, float]:
    """A target from ``reset(options=...)``: an ``(x, y)`` pair [m], finite, where the
    observation can show it (within +-OBS_BOUND * LENGTH_SCALE of the grid's origin)."""
    limit = plane_task.OBS_BOUND * plane_task.LENGTH_SCALE
    try:
        arr = np.asarray(target, dtype=float)
    except (TypeError, ValueError):
        arr = np.array([np.nan])
    if arr.shape != (2,) or not np.isfinite(arr).all() or np.abs(arr).max() > limit \
            or isinstance(target, (str, bytes)):
        raise ValueError(f"options['target'] = {target!r} is invalid: must be an (x, y) pair of "
                         f"finite positions [m] within ±{limit * 1e3:g} mm of actuator 0")
    return float(arr[0]), float(arr[1])


class PlaneConveyor(PartsBase):
    """``n`` parts on one :class:`PlaneEnvConfig`: their state, per-episode randomisation and
    step (see :mod:`.step` for ``parts``, ``consts``, ``action``, ``task``, ``out``).
    ``friction_factor`` / ``mass_factor``: each part's factors this episode (1 while
    randomisation is off). ``num_threads``: as :class:`~..core.threads.ThreadChooser` (the single
    env passes 1). The compiled calls hold these very arrays: write them in place, never rebind
    them. Pickles."""

    components = ("aim x", "aim y", "frequency", "stroke", "delay")
    step_info = (("actuator", "actuator", -1), ("frequency_hz", "frequency", 0.0),
                 ("stroke_m", "stroke", 0.0), ("delay_s", "delay", 0.0))

    def __init__(self, config: PlaneEnvConfig, n: int, num_threads: int | None = 1) -> None:
        self.config = config
        self.n = n
        self.sim = make_plane_simulator(config)
        pos = np.asarray(config.actuator_positions, dtype=np.float64).reshape(-1, 2)
        self.positions: np.ndarray = pos
        self.action = actions.constants(config, config.action_noise)
        self.task = plane_task.constants(config)
        self.parts = PlaneParts(x=np.zeros(n), y=np.zeros(n), vx=np.zeros(n), vy=np.zeros(n),
                                t=np.zeros(n), fired=np.zeros(n, dtype=np.int64),
                                tx=np.zeros(n), ty=np.zeros(n))
        tu, tq, tqu = self.sim.tables
        self.consts = PlaneConstants(
            dt=float(self.sim.dt), min_steps=int(self.sim.min_steps),
            ax=np.ascontiguousarray(pos[:, 0]), ay=np.ascontiguousarray(pos[:, 1]),
            P=np.tile(self.sim.params, (n, 1)),
            noise=(np.zeros((n, config.max_firings, randomisation.NOISE_COMPONENTS))
                   if config.action_noise > 0 else NO_NOISE),
            tu=tu, tq=tq, tqu=tqu, rec=NO_RECORD)
        self.out = PlaneOutputs(
            reward=np.zeros(n), outcome=np.zeros(n, dtype=np.int64),
            success=np.zeros(n, dtype=np.bool_), actuator=np.full(n, -1, dtype=np.int64),
            frequency=np.zeros(n), stroke=np.zeros(n), delay=np.zeros(n),
            obs=np.zeros((n, plane_task.OBS_DIM), dtype=np.float32),
            kernel=np.zeros((n, plane_kernel.N_OUT)))
        self.obs = self.out.obs  # every part's observation after the last step or observe
        self.obs_dim: int = plane_task.OBS_DIM
        self.obs_bound: float = plane_task.OBS_BOUND
        # per-episode randomisation: the factors drawn, and each part's streams with the
        # generator they were derived from (re-derived when it is replaced)
        self._start_randomisation(config, n)
        self._start(n, num_threads)

    def clear_targets(self) -> None:
        self.parts.tx[:] = self.parts.ty[:] = np.nan

    def errors(self) -> dict[str, np.ndarray]:
        """``position_error_m`` (n, 2): each part's (x − tx, y − ty) [m]; ``distance_m``: its
        Euclidean distance to the target [m]."""
        p = self.parts
        err = np.stack([p.x - p.tx, p.y - p.ty], 1)
        return {"position_error_m": err, "distance_m": np.hypot(err[:, 0], err[:, 1])}

    def compiled(self) -> tuple[Any, Any, Any, tuple[Any, ...]]:
        return step_serial, step_parallel, observe_all, (self.parts, self.task, self.out.obs)

    def table_simulator(self) -> Any:
        return self.sim.line

    def check_targets(self, given: Any, batched: bool) -> list[tuple[float, float]]:
        """Every part's target (:func:`check_plane_target`): an ``(x, y)`` pair [m] for every
        part or, ``batched``, an ``(n, 2)`` array, one per part."""
        if not batched:
            return [check_plane_target(given)]
        try:
            tv = np.asarray(given, dtype=float)
        except (TypeError, ValueError):
            return [check_plane_target(given)]  # not numbers: refused, naming them
        if tv.shape not in ((2,), (self.n, 2)):
            raise ValueError(f"options['target'] has shape {tv.shape}: must be (2,) or "
                             f"({self.n}, 2) [m]")
        if tv.ndim == 1:
            return [check_plane_target(given)] * self.n
        return [for_part(i, check_plane_target, tv[i]) for i in range(self.n)]

    def check_state(self, state: Any) -> PlaneState:
        """A saved part state checked against the config
        (:func:`.part_state.check_plane_state`)."""
        return check_plane_state(state, self.config)

    def reset_part(self, i: int, rng: np.random.Generator,
                   target: tuple[float, float] | None = None,
                   state: PlaneState | None = None) -> None:
        """Start part ``i``'s next episode: start and target from ``rng`` (``target`` overrides
        the drawn one), then, with randomisation on, its factors and noise from the streams
        derived from ``rng``; then ``state``, if given, in place of all that (its randomisation
        fields left None keep this episode's draws). ``target`` and ``state`` as
        :meth:`check_reset` gives them."""
        x0, y0, tx, ty = plane_task.initial_state(self.config, rng, target)
        self._draw_randomisation(i, rng)
        p = self.parts
        p.x[i], p.y[i], p.vx[i], p.vy[i], p.t[i] = x0, y0, 0.0, 0.0, 0.0
        p.fired[i] = 0
        p.tx[i], p.ty[i] = tx, ty
        if state is not None:
            (p.x[i], p.y[i]), (p.vx[i], p.vy[i]) = state.position_m, state.velocity_m_s
            p.t[i], p.fired[i] = state.time_s, state.fired
            p.tx[i], p.ty[i] = state.target_m
            self._restore_randomisation(i, state)

    def get_state(self, i: int, env_id: str | None = None) -> PlaneState:
        """Part ``i``'s state now (with randomisation on, its factors and noise too), naming
        ``env_id`` and this config's scene."""
        p = self.parts
        ff, mf, noise = self._saved_randomisation(i)
        return PlaneState((float(p.x[i]), float(p.y[i])), (float(p.vx[i]), float(p.vy[i])),
                          float(p.t[i]), int(p.fired[i]), (float(p.tx[i]), float(p.ty[i])),
                          ff, mf, noise, env_id, scene_of(self.config))
