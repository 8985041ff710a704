"""The deterministic actor of a stable-baselines3 policy, rebuilt from its saved tensors alone
(:func:`load_actor` from a model zip, :func:`actor_of_model` from a live model).

Evaluating a policy needs only its actor: the layers from observation to mean action. Here they
are rebuilt from the tensors of ``policy.pth`` (their names say which layer is which, their
shapes give the widths), so nothing that a model file *says* about its network (``net_arch``,
``n_critics``, ``buffer_size``, ``n_envs``) is built: a crafted file can ask for no memory beyond
the bytes of its own tensors, and no env, critic, optimizer or replay buffer is made.

The forward pass is SB3's, operation for operation (``torch.nn.Linear`` and the activation, in
float32, one row at a time as :class:`~agents.rl.artefacts.policy_files.Policy` calls it), so a rebuilt
actor gives the bit-identical action of SB3's ``predict(obs, deterministic=True)``:

* PPO (``ActorCriticPolicy``): ``action_net(policy_net(obs))``, Tanh by default, then clipped to
  the action box (``tanh`` first when the policy squashes its output);
* SAC, TQC (squashed Gaussian): ``tanh(mu(latent_pi(obs)))``, ReLU by default, then mapped from
  [-1, 1] to the action box with SB3's ``unscale_action`` arithmetic;
* TD3: ``mu(obs)`` (its last layer a Tanh), ReLU by default, mapped the same way.

Dict observations (the goal-conditioned env) are flattened key by key in the observation space's
order and concatenated, as SB3's ``CombinedExtractor`` does for Box sub-spaces.

The tensors must be the network the model's own ``policy_kwargs`` describe: the actor's hidden
widths are compared with its ``net_arch`` (SB3's default for the algorithm when none is given; not
checked when ``policy_kwargs`` is a pickle), so a layer added to or removed from ``policy.pth`` is
refused (:func:`actor_widths`, :func:`check_net_arch`). The network is a float32 network: both
forward passes, float32 (:meth:`ActorNet.predict`) and portable float64
(:meth:`ActorNet.predict_portable`), refuse an observation on which a layer's output leaves
float32's finite range (:class:`ActorOverflowError`) instead of acting on an overflow, so the two
agree on which observations a network can act on (up to rounding at the edge of the range).
"""
from __future__ import annotations

import binascii
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .model_zip import SERIALIZED, ModelFileError, open_model, read_data, read_weights
from .sb3_files import ALGOS, check_spaces, custom_objects, pickled_globals

MAX_WIDTH = 4096     # units in one layer
MAX_LAYERS = 16      # hidden layers
DEFAULT_ACTIVATION = {"ppo": "Tanh", "a2c": "Tanh", "sac": "ReLU", "tqc": "ReLU", "td3": "ReLU"}
# SB3 2.x's actor widths when policy_kwargs name no net_arch
DEFAULT_NET_ARCH = {"ppo": [64, 64], "a2c": [64, 64], "sac": [256, 256], "tqc": [256, 256],
                    "td3": [400, 300]}
FLOAT32_MAX = float(np.finfo(np.float32).max)


class ActorFileError(ValueError):
    """Saved tensors that do not form the actor of the algorithm named."""


class ActorOverflowError(ActorFileError):
    """A layer's output outside float32's finite range on an observation: the network cannot
    act on it (both forward passes refuse it rather than act on inf or NaN)."""


def actor_widths(net_arch: Any) -> list[int] | None:
    """The actor's hidden widths a ``net_arch`` describes (a list: shared by actor and critic;
    a dict: its ``pi``), or None when ``net_arch`` is not one of SB3's forms."""
    if isinstance(net_arch, dict):
        net_arch = net_arch.get("pi", [])
    if isinstance(net_arch, list) and all(isinstance(w, int) and not isinstance(w, bool)
                                          for w in net_arch):
        return list(net_arch)
    return None


def check_net_arch(actor: ActorNet, net_arch: Any, where: str) -> None:
    """ActorFileError when ``actor``'s hidden widths are not those ``net_arch`` describes
    (``where`` names the setting in the message); a ``net_arch`` of no known form is not
    compared."""
    want = actor_widths(net_arch)
    if want is not None and want != actor.hidden_widths:
        raise ActorFileError(f"holds an actor with hidden layers {actor.hidden_widths}, but "
                             f"{where} says {want}: the network is not the one described")


@dataclass(frozen=True)
class Layout:
    """Where an algorithm's actor lives in its state dict: the hidden layers' prefix (a
    ``Sequential`` whose Linear layers sit at even indices), the output layer's prefix (None:
    the Sequential's last Linear is the output layer), and whether the output is squashed by
    tanh and mapped from [-1, 1] to the action box."""

    hidden: str
    head: str | None
    squashed: bool


LAYOUTS = {
    "ppo": Layout("mlp_extractor.policy_net", "action_net", False),
    "a2c": Layout("mlp_extractor.policy_net", "action_net", False),
    "sac": Layout("actor.latent_pi", "actor.mu", True),
    "tqc": Layout("actor.latent_pi", "actor.mu", True),
    "td3": Layout("actor.mu", None, True),
}


def _linears(state: dict[str, Any], prefix: str) -> list[int]:
    """Indices ``i`` of ``prefix.i.weight`` in ``state``, sorted."""
    pat = re.compile(re.escape(prefix) + r"\.(\d+)\.weight$")
    return sorted(int(m.group(1)) for k in state if (m := pat.match(k)))


class ActorNet:
    """The deterministic actor of ``algo`` built from ``state`` (SB3's ``policy.state_dict()``
    tensors; only the actor's are used). ``obs_keys``: a Dict observation's keys in order (None:
    a Box observation). ``activation``: a ``torch.nn`` class name (default: the algorithm's).
    ``squash``: a PPO policy that squashes its output (gSDE's ``squash_output``).

    :attr:`module` is a ``torch.nn.Module`` whose parameter names are SB3's state-dict keys with
    ``.`` replaced by ``__`` (see :meth:`sb3_state`), so a fitted actor can be written back into
    the policy's ``policy.pth``."""

    def __init__(self, algo: str, state: dict[str, Any], obs_dim: int, action_low: np.ndarray,
                 action_high: np.ndarray, obs_keys: tuple[str, ...] | None = None,
                 activation: str | None = None, squash: bool = False) -> None:
        import torch

        if algo not in LAYOUTS:
            raise ActorFileError(f"no actor layout for {algo!r}")
        layout = LAYOUTS[algo]
        name = activation or DEFAULT_ACTIVATION[algo]
        act_cls = getattr(torch.nn, name, None)
        if act_cls is None:
            raise ActorFileError(f"unknown activation {name!r}")
        idx = _linears(state, layout.hidden)
        keys = [f"{layout.hidden}.{i}" for i in idx]
        if layout.head is None:
            if not keys:
                raise ActorFileError(f"no {layout.hidden}.<i>.weight tensors: not a "
                                     f"{algo.upper()} actor")
            keys, head = keys[:-1], keys[-1]
            idx = idx[:-1]
        else:
            head = layout.head
        if idx != list(range(0, 2 * len(idx), 2)):
            raise ActorFileError(f"{layout.hidden}: layers at {idx}, expected a Linear at every "
                                 "even index (Linear, activation, ...)")
        if len(keys) > MAX_LAYERS:
            raise ActorFileError(f"{len(keys)} hidden layers (at most {MAX_LAYERS})")
        n_act = int(np.prod(np.shape(action_low)))
        layers: list[tuple[str, Any, Any]] = []
        width = obs_dim
        for prefix in [*keys, head]:
            w, b = (_tensor(state, f"{prefix}.{what}") for what in ("weight", "bias"))
            out = n_act if prefix == head else None
            if (w.ndim != 2 or b.ndim != 1 or w.shape[1] != width or b.shape[0] != w.shape[0]
                    or (out is not None and w.shape[0] != out) or w.shape[0] > MAX_WIDTH):
                raise ActorFileError(
                    f"{prefix}: weight {tuple(w.shape)} and bias {tuple(b.shape)} do not chain "
                    f"from {width} inputs" + (f" to {out} actions" if out is not None else "")
                    + f" (widths at most {MAX_WIDTH})")
            layers.append((prefix, w, b))
            width = int(w.shape[0])
        self.algo, self.layout, self.activation = algo, layout, name
        self.obs_keys, self.obs_dim = obs_keys, obs_dim
        self.squash = layout.squashed or squash
        self.hidden_widths = [int(w.shape[0]) for _, w, _ in layers[:-1]]
        self.low = np.asarray(action_low, np.float32)
        self.high = np.asarray(action_high, np.float32)
        self.module = _Module(layers, act_cls, final_tanh=self.squash)
        # the same layers as float64 arrays, for predict_portable
        self._layers64 = [(w.detach().double().numpy(), b.detach().double().numpy())
                          for _, w, b in layers]

    def sb3_state(self) -> dict[str, Any]:
        """The actor's tensors under their SB3 state-dict keys (float32, detached copies)."""
        import torch

        return {k.replace("__", "."): v.detach().to(torch.float32).clone()
                for k, v in self.module.state_dict().items()}

    def features(self, obs: Any) -> Any:
        """A float32 tensor ``(n, obs_dim)`` of a batch of observations (a Dict's keys
        flattened and concatenated in order)."""
        import torch

        if self.obs_keys is not None:
            parts = [torch.as_tensor(np.asarray(obs[k])).float().reshape(len(obs[k]), -1)
                     for k in self.obs_keys]
            return torch.cat(parts, dim=1)
        x = torch.as_tensor(np.asarray(obs)).float()
        return x.reshape(x.shape[0], -1)

    def mean(self, x: Any) -> Any:
        """The actor's output for features ``x`` before the env's clipping (tanh-squashed where
        the algorithm squashes), differentiable."""
        return self.module(x)

    def predict(self, obs: Any) -> np.ndarray:
        """Deterministic actions for a batch of observations, as SB3's ``predict`` returns them
        (clipped to the box, or mapped to it from [-1, 1] for squashed outputs)."""
        import torch

        with torch.no_grad():
            a = self._checked_forward(self.features(obs)).cpu().numpy()
        a = a.reshape((-1, *self.low.shape))
        if self.squash:
            return self.low + (0.5 * (a + 1.0) * (self.high - self.low))
        return np.clip(a, self.low, self.high)

    def _checked_forward(self, x: Any) -> Any:
        """:meth:`mean` (the same operations, the same bits), refusing a layer output that is
        not finite in float32 (:class:`ActorOverflowError`)."""
        import torch

        def finite(name: str, out: Any) -> None:
            if not bool(torch.isfinite(out).all()):
                raise self._overflow(name.replace("__", "."))

        return self.module(x, on_layer=finite)

    @staticmethod
    def _overflow(layer: str) -> ActorOverflowError:
        return ActorOverflowError(f"layer {layer} leaves float32's finite range (|output| > "
                                  f"{FLOAT32_MAX:.3g}) on this observation: the network cannot "
                                  "act on it")

    def predict_portable(self, obs: Any) -> np.ndarray:
        """:meth:`predict` computed in float64 with IEEE operations in a fixed order only (each
        layer's sums by :func:`~microconveyor_env.physics.portable_math.ordered_dot`, tanh from
        its portable ``exp``), so the actions have the same bits on every CPU. torch's float32
        kernels differ by a few ULP between CPU code paths; a policy whose episodes amplify such
        differences (closed loop over many firings, each landing sensitive to where the part
        rested) is evaluated this way (its metadata's ``inference: "portable"``). Tanh and ReLU
        activations, Box observations. A layer output beyond float32's finite range (where the
        float32 network overflows) is refused as :meth:`predict` refuses it
        (:class:`ActorOverflowError`)."""
        from microconveyor_env.physics.portable_math import exp, ordered_dot

        if self.obs_keys is not None or self.activation not in ("Tanh", "ReLU"):
            raise ActorFileError(f"portable inference takes Box observations and a Tanh or "
                                 f"ReLU network, not {self.activation}")

        def act(z: np.ndarray) -> np.ndarray:
            if self.activation == "ReLU":
                return np.maximum(z, 0.0)
            e = exp(-2.0 * np.abs(z))
            return np.sign(z) * ((1.0 - e) / (1.0 + e))

        rows = []
        for x in np.asarray(obs, np.float64).reshape(len(obs), -1):
            for k, (w, b) in enumerate(self._layers64):
                x = ordered_dot(w, x) + b
                if not np.all(np.abs(x) <= FLOAT32_MAX):   # NaN fails the comparison too
                    raise self._overflow(self.module.names[k].replace("__", "."))
                if k < len(self._layers64) - 1:
                    x = act(x)
            rows.append(act(x) if self.squash and self.activation == "Tanh" else
                        (np.tanh(x) if self.squash else x))
        a = np.asarray(rows, np.float64).astype(np.float32).reshape((-1, *self.low.shape))
        if self.squash:
            return self.low + (0.5 * (a + 1.0) * (self.high - self.low))
        return np.clip(a, self.low, self.high)


def _tensor(state: dict[str, Any], key: str) -> Any:
    """``state[key]``: a finite float32 tensor, else :class:`ActorFileError`."""
    import torch

    t = state.get(key)
    if not isinstance(t, torch.Tensor) or t.dtype != torch.float32:
        raise ActorFileError(f"{key} is missing or not a float32 tensor")
    if not bool(torch.isfinite(t).all()):
        raise ActorFileError(f"{key} holds NaN or inf")
    return t


def _Module(layers: list[tuple[str, Any, Any]], act_cls: Any, final_tanh: bool) -> Any:
    """A ``torch.nn.Module``: Linear and ``act_cls`` alternating, the last Linear without an
    activation (then tanh if ``final_tanh``); parameter names from the SB3 prefixes."""
    import torch

    class ActorLayers(torch.nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.names: list[str] = []
            for prefix, w, b in layers:
                lin = torch.nn.Linear(int(w.shape[1]), int(w.shape[0]))
                with torch.no_grad():
                    lin.weight.copy_(w)
                    lin.bias.copy_(b)
                name = prefix.replace(".", "__")
                self.add_module(name, lin)
                self.names.append(name)
            self.act = act_cls()

        def forward(self, x: Any, on_layer: Any = None) -> Any:
            # on_layer(name, output): called with each linear layer's output (a check)
            for k, name in enumerate(self.names):
                x = getattr(self, name)(x)
                if on_layer is not None:
                    on_layer(name, x)
                if k < len(self.names) - 1:
                    x = self.act(x)
            return torch.tanh(x) if final_tanh else x

    return ActorLayers()


ACTIVATION_MODULE = "torch.nn.modules.activation."


def _activation(path: Path, data: dict[str, Any]) -> tuple[str | None, dict[str, Any]]:
    """The activation a model's ``policy_kwargs`` names (None: the algorithm's default) and its
    plain policy kwargs. A pickled ``policy_kwargs`` (SB3 pickles it when it holds a class) is
    read with :mod:`pickletools` only: the classes it names must be ``torch.nn`` activations of
    :data:`~agents.rl.training.hyperparams.ACTIVATIONS` (at most one) or ``torch.optim`` optimizers
    (irrelevant to acting)."""
    from ..training.hyperparams import ACTIVATIONS

    entry = data.get("policy_kwargs") or {}
    if not (isinstance(entry, dict) and SERIALIZED in entry):
        return None, dict(entry)
    try:
        names = pickled_globals(entry)
    except (ValueError, binascii.Error, TypeError) as exc:
        raise ModelFileError(f"{str(path)!r}: its policy_kwargs entry is not a readable "
                             f"pickle ({exc})") from None
    acts = [n[len(ACTIVATION_MODULE):] for n in names if n.startswith(ACTIVATION_MODULE)]
    other = [n for n in names if not n.startswith((ACTIVATION_MODULE, "torch.optim."))]
    if other or len(set(acts)) > 1 or not set(acts) <= set(ACTIVATIONS):
        raise ModelFileError(f"{str(path)!r}: its policy_kwargs name {names}; only one torch.nn "
                             f"activation ({', '.join(ACTIVATIONS)}) and torch.optim classes "
                             "are understood, so the model is refused")
    if data.get("use_sde"):
        raise ModelFileError(f"{str(path)!r}: a gSDE policy with pickled policy_kwargs: whether "
                             "it squashes its output cannot be read without unpickling")
    return (acts[0] if acts else None), {}


def flat_obs(observation_space: Any) -> tuple[int, tuple[str, ...] | None]:
    """The flattened observation size and, for a Dict space, its keys in order."""
    from gymnasium import spaces

    if isinstance(observation_space, spaces.Dict):
        keys = tuple(observation_space.spaces)
        return sum(int(np.prod(observation_space[k].shape or ())) for k in keys), keys
    return int(np.prod(observation_space.shape)), None


def load_actor(path: Path, algo: str, observation_space: Any, action_space: Any,
               zf: Any = None) -> ActorNet:
    """The deterministic actor of the model zip at ``path`` (an ``algo`` model for these
    spaces; ``zf``: the zip already opened with :func:`~.model_zip.open_model`), rebuilt from
    its ``policy.pth`` tensors (:class:`~.actor_net.ActorNet`): no SB3 model, env, critic or
    buffer is built, and no pickle is loaded."""
    zf = zf or open_model(path)
    data = read_data(path, zf)
    check_spaces(path, data, observation_space, action_space, "the env")
    if data.get("policy_class") is not None:
        custom_objects(path, {"policy_class": data["policy_class"]}, algo, observation_space,
                       action_space)   # the class it names must be the algorithm's policy
    activation, kwargs = _activation(path, data)
    squash = bool(data.get("use_sde")) and bool(kwargs.get("squash_output"))
    state = read_weights(path, "policy.pth", zf)
    obs_dim, keys = flat_obs(observation_space)
    pickled = isinstance(data.get("policy_kwargs"), dict) and SERIALIZED in data["policy_kwargs"]
    try:
        actor = ActorNet(algo, state, obs_dim, action_space.low, action_space.high, keys,
                         activation, squash)
        if not pickled:   # a pickle's net_arch is not read; its tensors are still chained
            check_net_arch(actor, kwargs.get("net_arch", DEFAULT_NET_ARCH.get(algo)),
                           "its data's policy_kwargs.net_arch")
    except ActorFileError as exc:
        raise ModelFileError(f"{str(path)!r}: policy.pth {exc}") from None
    return actor


def actor_of_model(model: Any) -> ActorNet:
    """The deterministic actor of a live SB3 model (a copy of its actor's tensors), as
    :func:`load_actor` builds it from a file: one forward pass for both."""
    algo = next((name for name in ALGOS for cls in type(model).__mro__
                 if cls.__name__.lower() == name), None)
    if algo is None:
        raise ValueError(f"no actor layout for a {type(model).__name__} model")
    policy = model.policy
    obs_dim, keys = flat_obs(model.observation_space)
    act = getattr(policy, "activation_fn", None)
    return ActorNet(algo, {k: v.detach().clone() for k, v in policy.state_dict().items()},
                    obs_dim, model.action_space.low, model.action_space.high, keys,
                    act.__name__ if act is not None else None,
                    bool(getattr(policy, "squash_output", False)) and algo in ("ppo", "a2c"))
