"""The network DAgger trains (:mod:`.dagger`): SB3 PPO's actor inside a PPO model with frozen
observation normalisation, fitted by regression to the expert's labels (Adam over epochs, or
full-batch L-BFGS in float64 through :func:`agents.rl.refinement.fit.fit`), and written as an
ordinary PPO policy folder that loads as data."""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from ..rl.artefacts.folders import NewPolicyFolder


class _MeanOf:
    """The student's actor as :func:`agents.rl.refinement.fit.fit` fits one (``net``,
    ``features``, ``mean``)."""

    def __init__(self, student: Student) -> None:
        import torch

        pol = student.model.policy
        self.net = torch.nn.ModuleList([pol.mlp_extractor.policy_net, pol.action_net])
        self.student = student

    def features(self, obs: np.ndarray) -> Any:
        import torch

        return torch.as_tensor(self.student.normalise(obs))

    def mean(self, x: Any) -> Any:
        return self.student.forward(x)


def _WithRequest(venv: Any) -> Any:
    """``venv`` seen with one more observation entry (a request-conditioned student's input:
    :func:`agents.rl.artefacts.policy_files.with_request`); it only gives the model its spaces,
    and is never stepped."""
    from stable_baselines3.common.vec_env import VecEnvWrapper

    from ..rl.artefacts.policy_files import with_request

    class WithRequest(VecEnvWrapper):
        def reset(self) -> Any:
            raise NotImplementedError("the student's env only gives the model its spaces")

        def step_wait(self) -> Any:
            raise NotImplementedError("the student's env only gives the model its spaces")

    return WithRequest(venv, observation_space=with_request(venv.observation_space))


class Student:
    """SB3 PPO's actor inside a PPO model, fitted by regression (module docstring). ``s``: the
    run's :class:`~.dagger.DaggerSettings` (its seed, network and fit fields); ``cfg``: the
    scene's config."""

    def __init__(self, s: Any, cfg: Any) -> None:
        import torch
        from stable_baselines3 import PPO
        from stable_baselines3.common.vec_env import VecNormalize

        from microconveyor_env.envs.core.sb3 import MicroConveyorSB3VecEnv

        torch.manual_seed(s.seed)
        inner: Any = MicroConveyorSB3VecEnv(1, config=cfg)
        if getattr(s, "requests", None) is not None:   # the observation, then the request's
            inner = _WithRequest(inner)
        self.venv = VecNormalize(inner, norm_obs=True, norm_reward=False, training=False)
        arch = list(s.net_arch)
        self.model = PPO("MlpPolicy", self.venv, seed=s.seed, device="cpu", verbose=0,
                         policy_kwargs={"net_arch": {"pi": arch, "vf": [64, 64]},
                                        "log_std_init": -3.0})
        pol = self.model.policy
        self.params = [*pol.mlp_extractor.policy_net.parameters(), *pol.action_net.parameters()]
        self.opt = torch.optim.Adam(self.params, lr=s.learning_rate)
        self.rng = np.random.default_rng(s.seed)
        self.s = s

    def normalise(self, obs: np.ndarray) -> np.ndarray:
        out = self.venv.normalize_obs(obs.astype(np.float32))
        assert isinstance(out, np.ndarray)   # a Box observation
        return out

    def set_stats(self, X: np.ndarray) -> None:
        rms = self.venv.obs_rms
        assert not isinstance(rms, dict)      # a Box observation
        rms.mean, rms.var, rms.count = X.mean(0).astype(np.float64), \
            X.var(0).astype(np.float64), float(len(X))

    def forward(self, obs_n: Any) -> Any:
        pol = self.model.policy
        return pol.action_net(pol.mlp_extractor.policy_net(obs_n))

    def fit(self, X: np.ndarray, Y: np.ndarray) -> float:
        """Fit to the data set (``s.fit``); returns the mean squared error per action
        component [action units²]: Adam's last batch, L-BFGS's whole set."""
        if self.s.fit == "lbfgs":
            from ..rl.refinement.fit import fit

            return fit(_MeanOf(self), X, Y, self.s.fit_iterations)[1] / Y.shape[1]
        return self._adam(X, Y)

    def _adam(self, X: np.ndarray, Y: np.ndarray) -> float:
        import torch

        xs = torch.as_tensor(self.normalise(X))
        ys = torch.as_tensor(Y, dtype=torch.float32)
        n, bs = len(xs), self.s.batch_size
        loss_v = 0.0
        for _ in range(self.s.epochs):
            order = torch.as_tensor(self.rng.permutation(n))
            for k in range(0, n, bs):
                idx = order[k:k + bs]
                loss = ((self.forward(xs[idx]) - ys[idx]) ** 2).mean()
                self.opt.zero_grad()
                loss.backward()
                self.opt.step()
                loss_v = loss.item()
        for group in self.opt.param_groups:
            group["lr"] *= self.s.lr_decay
        return loss_v

    def act(self, obs: np.ndarray) -> np.ndarray:
        import torch

        with torch.no_grad():
            a = self.forward(torch.as_tensor(self.normalise(obs))).numpy()
        return np.clip(a, -1.0, 1.0)

    def write_files(self, folder: Path) -> None:
        """Write the policy's model zip and observation statistics into ``folder``."""
        from ..rl.artefacts import normalization
        from ..rl.artefacts.checkpoint import MODEL, NORMALIZATION

        self.model.save(folder / MODEL)
        normalization.write(self.venv, folder / NORMALIZATION)

    def save(self, out: str | Path | NewPolicyFolder, meta: dict[str, Any]) -> Path:
        """Write the policy as the new policy folder ``out`` (or one already held) with
        ``meta`` and the files' sha256 in its metadata, atomically
        (:func:`agents.rl.artefacts.folders.write_policy_folder`)."""
        from ..rl.artefacts.folders import write_policy_folder

        def files(folder: Path) -> dict[str, Any]:
            self.write_files(folder)
            return meta
        return write_policy_folder(out, files)
