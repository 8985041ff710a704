"""One conveyor of N parts: the state and the step that the single env (N = 1) and the batched
env share.

As brax's typed ``State`` ("write once, vectorise"): the state is a few typed NamedTuples of
arrays, one element or row per part (:mod:`.step`, where the compiled code that reads them lives:
:class:`~.step.Parts`, :class:`~.step.Constants`, :class:`~.step.Outputs`, with
:class:`~..core.actions.ActionConstants` and :class:`~.task.TaskConstants`), and :class:`Conveyor`
owns them and implements, once for both envs,

* the reset options of all parts (targets, saved states), checked whole before any part changes
  (:meth:`Conveyor.check_reset`), and the reset of one part: its initial state and target
  (:func:`~..rail.parts.initial_state`), its randomisation streams (derived from the part's generator,
  re-derived when the generator is replaced) and draws (:mod:`..core.randomisation`), or a saved state;
* the step of all parts: one compiled call (:func:`.step.step_serial` or, chosen by
  :class:`~..core.threads.ThreadChooser`, :func:`.step.step_parallel`) with its arguments built once,
  through the container every rail's scene shares (:class:`~..rail.parts.RailParts`).

Everything Gym-specific (spaces, seeding, info dicts, autoreset, rendering) stays in the envs.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ...physics import dynamics_kernel as kernel
from ..core import actions
from ..core.versions import scene_of
from ..rail.parts import RailParts, initial_state, initial_states
from ..rail.step import OBS_BOUND
from . import task
from .config import EnvConfig
from .part_state import PartState, check_state
from .step import Outputs, Parts, observe_all, step_parallel, step_serial

Streams = tuple[np.random.Generator, np.random.Generator]
# One remembered firing of the observation history (EnvConfig.observe_history): the observation
# row before it (task.OBS_DIM), the action as commanded (actions.ACTION_DIM, clipped to the box
# [-1, 1] as the decoding clips it, before execution noise) and 1.0 (the slot holds a firing; an
# empty slot is all zeros)
HISTORY_ROW = task.OBS_DIM + actions.ACTION_DIM + 1
__all__ = ["HISTORY_ROW", "Conveyor", "conveyor_field"]


class Conveyor(RailParts):
    """``n`` parts on one configuration: their state, per-episode randomisation and step.

    ``parts`` (x, v, t, fired, target), ``consts`` (dt, min_steps, positions, P, noise, tables),
    ``action`` / ``task`` (constants), ``out`` (the last step's outputs): see :mod:`.step`.
    ``obs`` (n, ``obs_dim``): the observations the envs return, each part's row and, with
    ``observe_history`` k > 0, its k latest firings (``history``, a view; ``out.obs`` itself when
    k = 0). ``friction_factor`` / ``mass_factor``: each part's factors this episode (1 while
    randomisation is off). ``num_threads``: as :class:`~..core.threads.ThreadChooser` (the single env
    passes 1: always the serial loop). The compiled calls hold these very arrays: write them in
    place, never rebind them. Pickles (the compiled calls are rebuilt after loading).
    """

    config: EnvConfig
    step_info = (("frequency_hz", "frequency", 0.0), ("stroke_m", "stroke", 0.0),
                 ("delay_s", "delay", 0.0))

    def __init__(self, config: EnvConfig, n: int, num_threads: int | None = 1) -> None:
        self._start_rail(config, n, config.n_actuators)  # a noise row per actuator
        self.task = task.constants(config)
        self.parts = Parts(x=np.zeros(n), v=np.zeros(n), t=np.zeros(n),
                           fired=np.zeros(n, dtype=np.int64), target=np.zeros(n))
        self.out = Outputs(reward=np.zeros(n), outcome=np.zeros(n, dtype=np.int64),
                           success=np.zeros(n, dtype=np.bool_), frequency=np.zeros(n),
                           stroke=np.zeros(n), delay=np.zeros(n),
                           obs=np.zeros((n, task.OBS_DIM), dtype=np.float32),
                           kernel=np.zeros((n, kernel.N_OUT)))
        # per-episode randomisation (randomisation.py): the factors drawn, and each part's streams
        # with the generator they were derived from (re-derived when it is replaced)
        self._start_randomisation(config, n)
        # the observations the envs return: with observe_history k > 0, each part's row followed
        # by its k most recent firings (HISTORY_ROW numbers each, the latest first); with k = 0,
        # the compiled step's own rows (``out.obs``, the same array: nothing is copied)
        self.history_len: int = config.observe_history
        self.obs_dim: int = task.OBS_DIM + self.history_len * HISTORY_ROW
        self.obs_bound: float = OBS_BOUND
        self.obs: np.ndarray = (self.out.obs if self.history_len == 0 else
                                np.zeros((n, self.obs_dim), dtype=np.float32))
        # the compiled calls' inputs (owned, so their types never change) and the calls; the envs
        # check their actions straight into ``action_input`` (core.checks.check_actions(out=...))
        self._start(n, num_threads)
        if self.history_len:   # each step adds the firing to the observation history
            self.after_step = self._remember_all

    def compiled(self) -> tuple[Any, Any, Any, tuple[Any, ...]]:
        return step_serial, step_parallel, observe_all, (self.parts, self.positions, self.task,
                                                         self.out.obs)

    # ------------------------------------------------------------------ reset
    def check_state(self, state: Any) -> PartState:
        """A saved part state checked against the config (:func:`.part_state.check_state`)."""
        return check_state(state, self.config)

    def reset_part(self, i: int, rng: np.random.Generator, target: float | None = None,
                   state: PartState | None = None) -> None:
        """Start part ``i``'s next episode: start and target from ``rng`` (``target`` overrides
        the drawn one), then, with randomisation on, its factors and noise from the streams
        derived from ``rng``; then ``state``, if given, in place of all that (its fields left
        None keep this episode's draws). ``target`` and ``state`` as :meth:`check_reset` gives
        them."""
        x0, tgt = initial_state(self.config, rng, target)
        self._draw_randomisation(i, rng)
        self._write_start(i, x0, tgt)
        if state is not None:
            self._set_state(i, state)

    def reset_parts(self, rows: np.ndarray, rngs: Sequence[np.random.Generator]) -> None:
        """:meth:`reset_part` without options for the parts ``rows`` (ascending), part
        ``rows[k]`` drawing from ``rngs[k]``: the same draws, each part's state written with
        whole-array writes."""
        x0, tgt = initial_states(self.config, rngs)
        self._draw_randomisation_many(rows, rngs)
        self._write_start(rows, x0, tgt)

    def _write_start(self, rows: Any, x0: Any, tgt: Any) -> None:
        """Write a new episode's start into the parts ``rows`` (an index or an index array):
        at ``x0`` [m], still, nothing fired, aiming at ``tgt`` [m], no history."""
        p = self.parts
        p.x[rows], p.v[rows], p.t[rows] = x0, 0.0, 0.0
        p.fired[rows] = 0
        p.target[rows] = tgt
        if self.history_len:
            self.obs[rows, task.OBS_DIM:] = 0.0  # a new episode remembers no firing

    def get_state(self, i: int, env_id: str | None = None) -> PartState:
        """Part ``i``'s state now (with randomisation on, its factors and noise too; not the
        observation history: an episode started from it starts with an empty history), naming
        ``env_id`` and this config's scene."""
        p = self.parts
        ff, mf, noise = self._saved_randomisation(i)
        return PartState(float(p.x[i]), float(p.v[i]), float(p.t[i]), int(p.fired[i]),
                         float(p.target[i]), ff, mf, noise, env_id, scene_of(self.config))

    def _set_state(self, i: int, s: PartState) -> None:
        """Put part ``i`` in the checked state ``s``, after its reset (so the fields ``s``
        leaves None keep this episode's draws)."""
        p = self.parts
        p.x[i], p.v[i], p.t[i] = s.position_m, s.velocity_m_s, s.time_s
        p.fired[i] = s.fired
        p.target[i] = s.target_m
        self._restore_randomisation(i, s)

    # ------------------------------------------------------------------ step
    @property
    def history(self) -> np.ndarray:
        """The observation history, ``(n, observe_history, HISTORY_ROW)`` float32, a view into
        ``obs`` (slot 0: the latest firing)."""
        return self.obs[:, task.OBS_DIM:].reshape(self.n, self.history_len, HISTORY_ROW)

    def observe(self) -> np.ndarray:
        """Every part's observation, into (and returned as) ``obs``: copy to keep it. The
        history is not changed (only a step adds to it, a reset empties it)."""
        self._observe()
        if self.history_len:
            self.obs[:, :task.OBS_DIM] = self.out.obs
        return self.obs

    def _remember_all(self) -> None:
        self._remember(self._all_active)

    def _remember(self, everyone: bool) -> None:
        """After a step: each active part's history shifts by one slot and slot 0 takes the
        firing just made (the row ``obs`` held before it and the commanded action); then every
        part's row is the step's."""
        od, ad = task.OBS_DIM, actions.ACTION_DIM
        hist = self.history
        rows: slice | np.ndarray = slice(None) if everyone else np.flatnonzero(self._active)
        count = self.n if everyone else int(self._active.sum())
        latest = np.empty((count, HISTORY_ROW), dtype=np.float32)
        latest[:, :od] = self.obs[rows, :od]
        np.clip(self.action_input[rows], -1.0, 1.0, out=latest[:, od:od + ad])  # as decoded
        latest[:, od + ad] = 1.0
        hist[rows, 1:] = hist[rows, :-1].copy()
        hist[rows, 0] = latest
        self.obs[:, :od] = self.out.obs


def conveyor_field(path: str, doc: str) -> Any:
    """A read-only property for ``self.conveyor.<path>`` (dotted), e.g. ``"parts.x"``."""
    names = path.split(".")

    def get(self: Any) -> Any:
        obj: Any = self.conveyor
        for name in names:
            obj = getattr(obj, name)
        return obj

    return property(get, doc=doc)
