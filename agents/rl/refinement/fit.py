"""The actor refined (:mod:`.refine`): the mean action of a Gaussian actor before the env's
clipping (:class:`MeanActor`), and fitting it to corrected actions (:func:`fit`)."""
from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from ..artefacts.policy_files import Policy


class FittedActor(Protocol):
    """What :func:`fit` fits: a torch module ``net`` holding the parameters, the network's
    input for raw observations (``features``) and its mean action for that input (``mean``)."""

    net: Any

    def features(self, obs: np.ndarray) -> Any: ...

    def mean(self, x: Any) -> Any: ...


class MeanActor:
    """The mean action of a Gaussian actor (PPO's) *before* the env's clipping, for a batch of
    raw observations (normalised as in training); ``net`` is the torch module fitted."""

    def __init__(self, policy: Policy) -> None:
        self.policy_actor = policy.actor
        self.net = policy.actor.module
        self.normalizer = policy.normalizer

    def features(self, obs: np.ndarray) -> Any:
        import torch

        x = self.normalizer(obs) if self.normalizer is not None else obs.astype(np.float32)
        return torch.as_tensor(x, dtype=torch.float32)

    def mean(self, x: Any) -> Any:
        return self.policy_actor.mean(x)

    def raw(self, obs: np.ndarray) -> np.ndarray:
        import torch

        with torch.no_grad():
            return self.mean(self.features(obs)).numpy().astype(np.float32)

    def act(self, obs: np.ndarray) -> np.ndarray:
        """:meth:`raw`: the actor as :func:`~microconveyor_env.envs.core.episodes.run_episodes`
        plays it (the env clips)."""
        return self.raw(obs)


def fit(actor: FittedActor, obs: np.ndarray, actions: np.ndarray, iterations: int) -> tuple[float, float]:
    """Fit the actor's mean to ``actions`` at ``obs`` (rows of a batch) as the env fires them:
    both clipped to the box, so a mean beyond the box whose label is beyond it too costs nothing.
    Full-batch L-BFGS in float64 (the fit must resolve action changes of ~1e-3, which move a far
    target's landing by tens of µm); the weights go back to float32. Returns the mean squared
    error [action units²] before and after."""
    import torch

    net = actor.net
    params = list(net.parameters())
    net.to(torch.float64)
    try:
        x = actor.features(obs).to(torch.float64)
        y = torch.as_tensor(np.clip(actions, -1.0, 1.0), dtype=torch.float64)

        def loss() -> Any:
            return ((actor.mean(x).clamp(-1.0, 1.0) - y) ** 2).sum(1).mean()

        with torch.no_grad():
            before = float(loss())
        opt = torch.optim.LBFGS(params, lr=1.0, max_iter=iterations, history_size=50,
                                line_search_fn="strong_wolfe", tolerance_grad=1e-12,
                                tolerance_change=1e-14)

        def closure() -> Any:
            opt.zero_grad()
            value = loss()
            value.backward()
            return value

        opt.step(closure)
        with torch.no_grad():
            after = float(loss())
    finally:
        net.to(torch.float32)
    return before, after
