"""One episode per sub-env of a batched env, played to its end by an actor: the one episode loop
every evaluation, refinement and open-loop search uses, for any registered id's batched env
(the line's or the plane's).

An :class:`Actor` is anything with ``act(observations) -> actions`` over a batch (a loaded
policy, a network's mean action, a batch of open-loop plans: :class:`PlanActor`).
:func:`run_episodes` steps the env with the actor's actions until every sub-env's first episode
has ended and returns :class:`EpisodeRecords`: each episode's final info (the values of the env's
info at the step it ended), its number of firings and, on request, the observation before and
the action of every firing.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np


class Actor(Protocol):
    """Anything that acts on a batch: ``act(observations (B, obs)) -> actions (B, act)``."""

    def act(self, obs: np.ndarray) -> np.ndarray: ...


class PlanActor:
    """Open-loop plans ``(B, firings, act)`` as an actor: the ``k``-th call returns every plan's
    ``k``-th action as float32 (what the env is given), whatever the observation."""

    def __init__(self, plans: np.ndarray) -> None:
        self.plans = np.asarray(plans)
        self.k = 0

    def act(self, obs: np.ndarray) -> np.ndarray:
        a = self.plans[:, self.k].astype(np.float32)
        self.k += 1
        return a


@dataclass
class EpisodeRecords:
    """Per-episode records of a batch (arrays over it). ``final``: each key of the env's step
    info (the episode's ``final_info`` under same-step autoreset) at the step the episode
    ended; ``ended``: whether it ended within the steps played; ``firings``: the steps it took.
    With ``keep_steps``: ``obs`` ``(B, S, obs)`` before each step, ``actions`` ``(B, S, act)``
    the actor's (before ``clip``), ``taken`` ``(B, S)`` whether the episode took step ``k``
    (``S``: ``max_steps`` if given, else the steps played; rows past an episode's end are zero)."""

    final: dict[str, np.ndarray]
    ended: np.ndarray
    firings: np.ndarray
    obs: np.ndarray | None = None
    actions: np.ndarray | None = None
    taken: np.ndarray | None = None


def _blank(value: np.ndarray) -> np.ndarray:
    """An array of ``value``'s shape and kind holding "not ended": NaN, False, 0 or ''."""
    kind = value.dtype.kind
    if kind in "fc":
        return np.full(value.shape, np.nan, value.dtype)
    if kind in "biu":
        return np.zeros(value.shape, value.dtype)
    return np.full(value.shape, "", dtype=object)


def run_episodes(env: Any, actor: Actor, seed: int | list[int] | None = 0,
                 options: dict[str, Any] | None = None, max_steps: int | None = None,
                 clip: bool = False, keep_steps: bool = False,
                 on_step: Callable[[Any, dict[str, Any], np.ndarray, np.ndarray], None] | None = None
                 ) -> EpisodeRecords:
    """Reset ``env`` (a batched env of any registered id) with ``seed`` and ``options`` and play
    one episode per sub-env with ``actor`` until all have ended (or ``max_steps`` steps).
    ``clip``: the env is given the actions clipped to [-1, 1] (the records keep the actor's).
    ``on_step(env, final_info, new, done)``: called after each step with the episodes that
    ended at it (``new``) and by then (``done``)."""
    obs, _ = env.reset(seed=seed, options=options or {})
    n = env.num_envs
    done = np.zeros(n, bool)
    firings = np.zeros(n, dtype=int)
    final: dict[str, np.ndarray] = {}
    steps: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []   # copies: the env reuses buffers
    played = 0
    while not done.all() and (max_steps is None or played < max_steps):
        a = actor.act(obs)
        if keep_steps:
            steps.append((np.array(obs, np.float32), np.array(a, np.float32), ~done))
        played += 1
        obs, _, term, trunc, info = env.step(np.clip(a, -1.0, 1.0) if clip else a)
        src = info.get("final_info", info)
        new = (term | trunc) & ~done
        for key, value in src.items():
            if key.startswith("_") or key in ("final_obs", "final_info"):
                continue
            value = np.asarray(value)
            if value.shape[:1] != (n,):
                continue
            if key not in final:
                final[key] = _blank(value)
            final[key][new] = value[new]
        firings[~done] += 1
        done |= term | trunc
        if on_step is not None:
            on_step(env, src, new, done)
    out = EpisodeRecords(final, done.copy(), firings)
    if keep_steps:
        s = max_steps if max_steps is not None else len(steps)
        o, a, t = steps[0]
        out.obs = np.zeros((n, s, *o.shape[1:]), np.float32)
        out.actions = np.zeros((n, s, *a.shape[1:]), np.float32)
        out.taken = np.zeros((n, s), bool)
        for k, (o, a, t) in enumerate(steps):
            out.obs[:, k], out.actions[:, k], out.taken[:, k] = o, a, t
    return out
