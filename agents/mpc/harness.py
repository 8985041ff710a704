"""MPC episodes of many targets, on worker processes: the harness experiments run the controller
(:mod:`.control`) with, on any scene it serves.

:class:`MPCRollout` is a rollout function ``(config, targets, seed) -> dict`` as
:mod:`agents.experiments.perturb` runs them. Its episodes are split into batches, one per worker
of a process pool (started once, with ``spawn``); the results do not depend on the number of
workers. A worker that dies breaks the pool for every batch not yet finished: those batches run
again, each in a supervised process of its own, and a batch whose process dies too comes back as
failed episodes (outcome ``"worker_died"``, error NaN) while the others stand.
"""
from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from microconveyor_env.envs.core.versions import nominal

from ..planning import scene_of
from .control import MPC, MPCEpisode, MPCSettings, OneStepSettings

Settings = MPCSettings | OneStepSettings

LOST = "worker_died"   # the outcome of an episode whose batch's process died twice


class Batch(NamedTuple):
    """One worker's share of a call: the episodes numbered ``numbers`` (in the whole call, for
    the search seeds) towards ``targets`` [m], env seeds ``seeds``, on ``config``, planned on ``model`` (None:
    ``config`` made nominal) with ``settings``, seeded by the policy folder ``prior``."""

    config: Any
    model: Any
    settings: Settings | None
    targets: np.ndarray
    seeds: np.ndarray
    numbers: np.ndarray
    prior: str | None = None


def _episodes(batch: Batch) -> list[MPCEpisode]:
    """The MPC episodes of ``batch`` (a worker's function): episode ``i`` seeded ``seeds[i]``,
    its searches ``settings.seed + 1000 numbers[i]``."""
    policy = None
    if batch.prior is not None:
        from ..rl.artefacts.policy_files import load_policy

        policy = load_policy(batch.prior)
    ctl = MPC(batch.model or nominal(batch.config), batch.settings, policy)
    env = scene_of(batch.config).env()
    return [ctl.run(env, float(tg), int(sd), search_seed=ctl.seed + 1000 * int(i))
            for tg, sd, i in zip(batch.targets, batch.seeds, batch.numbers, strict=True)]


def _lost_episodes(batch: Batch, why: object) -> list[MPCEpisode]:
    """The episodes of a batch whose worker died twice: failed, error NaN, no compute."""
    return [MPCEpisode(float(t), float("nan"), LOST, False, float("nan"), 0, 0, 0.0)
            for t in batch.targets]


class MPCRollout:
    """A rollout function ``(config, targets, seed) -> dict`` as :mod:`agents.experiments.perturb`
    runs them: episode ``i`` is the single env of ``config`` seeded ``seed + i`` (the same episode
    as sub-env ``i`` of the batched env), controlled by an :class:`~.control.MPC` with
    ``settings`` (:class:`~.control.MPCSettings` on the line, :class:`~.control.OneStepSettings`
    on the positioner; None: the scene's default) planning on ``model`` (default: ``config``
    with randomisation off), its searches seeded ``settings.seed + 1000 i``; ``prior``: a policy folder whose plan on the model seeds every
    search, loaded in each worker as data. ``workers`` [-] processes share the targets (started
    once, on the first call, with ``spawn``: numba's thread pool does not survive a fork; the
    results do not depend on the number of workers; a worker ends when this process does, however
    it ends); :meth:`close` (or ``with``) stops them. The dict also holds the compute per target:
    ``episodes`` (of the model) and ``wall_time_s`` (planning), and the model's
    ``estimated_friction_factor``. ``worker_deaths`` counts the pools a dead worker broke."""

    def __init__(self, settings: Settings | None = None, model: Any = None,
                 workers: int = 1, prior: str | None = None) -> None:
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
            raise ValueError(f"workers = {workers!r} is invalid: must be an integer >= 1")
        self.settings, self.model, self.workers = settings, model, workers
        self.prior = None if prior is None else str(prior)
        self._pool: Any = None
        self.worker_deaths = 0   # pools broken by a dead worker so far

    def __call__(self, config: Any, targets: np.ndarray, seed: int) -> dict:
        tg = np.asarray(targets, float)
        index = np.arange(tg.size)
        seeds = seed + index
        k = min(self.workers, tg.size)
        if k <= 1:
            eps = _episodes(Batch(config, self.model, self.settings, tg, seeds, index,
                                  self.prior))
        else:
            batches = [Batch(config, self.model, self.settings, tg[p], seeds[p], p, self.prior)
                       for p in np.array_split(index, k)]
            eps = [e for done in self._run_batches(batches) for e in done]
        out: dict[str, Any] = {
            "targets_m": tg,
            "error_m": np.array([e.error_m for e in eps]),
            "outcome": np.array([e.outcome for e in eps], dtype=object),
            "success": np.array([e.success for e in eps]),
            "time_s": np.array([e.time_s for e in eps]),
            "firings": np.array([e.firings for e in eps]),
            "episodes": np.array([e.episodes for e in eps]),
            "wall_time_s": np.array([e.wall_time_s for e in eps]),
            "estimated_friction_factor": np.array([e.estimated_factors[0] for e in eps])}
        if config.randomised:  # what the env drew for episode i (seed + i), as rollout() reports
            out["friction_factor"] = np.array([e.friction_factor for e in eps])
            out["mass_factor"] = np.array([e.mass_factor for e in eps])
        return out

    def _start_pool(self) -> Any:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor

        from ..rl.training.parallel import exit_with_parent

        # a worker ends with its parent (killed or not), instead of waiting for tasks
        return ProcessPoolExecutor(self.workers, mp_context=mp.get_context("spawn"),
                                   initializer=exit_with_parent)

    def _run_batches(self, batches: list[Batch]) -> list[list[MPCEpisode]]:
        """Each batch of episodes on the pool. When a worker dies, the pool is broken for every
        batch not yet finished: those batches run again, each in a supervised process of its
        own (:func:`agents.rl.training.parallel.run_local`), and a batch whose process dies again
        counts as failed episodes (:func:`_lost_episodes`) while the others stand."""
        from concurrent.futures.process import BrokenProcessPool

        if self._pool is None:
            self._pool = self._start_pool()
        done: list[list[MPCEpisode] | None] = [None] * len(batches)
        try:   # a worker that died between calls breaks the pool at submit already
            futures = [self._pool.submit(_episodes, b) for b in batches]
        except BrokenProcessPool:
            futures = []
        for i, f in enumerate(futures):
            try:
                done[i] = f.result()
            except BrokenProcessPool:
                pass
        redo = [i for i, eps in enumerate(done) if eps is None]
        if redo:
            from ..rl.training.parallel import Died, run_local

            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None   # started again at the next call
            self.worker_deaths += 1
            again = run_local(_episodes, [batches[i] for i in redo], self.workers,
                              died=lambda b, err: Died(_lost_episodes(b, err)))
            for i, eps in zip(redo, again, strict=True):
                done[i] = eps
        return [eps or [] for eps in done]

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    def __enter__(self) -> MPCRollout:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def mpc_rollout(settings: Settings | None = None, model: Any = None,
                workers: int = 1, prior: str | None = None) -> MPCRollout:
    """:class:`MPCRollout` (``settings``, ``model``, ``workers``; ``prior``: a policy folder
    whose plan on the model seeds every search, loaded in each worker as data)."""
    return MPCRollout(settings, model, workers, prior)
