"""The search space of ``microconveyor tune`` (PPO) and the best trial as an rl-zoo3 config entry.

Sampled as rl-zoo3's ``sample_ppo_params`` does (``rl_zoo3/hyperparams_opt.py``): sizes as powers
of two (``*_pow``), ``1 - gamma`` on a log scale, categorical epochs and widths; ranges narrowed
to this task (episodes of at most 5 steps: short rollouts of many envs). Everything else comes
from the base config entry (``configs/ppo.yml`` or ``--conf-file``). A parameter given in
``fixed`` is not sampled.
"""
from __future__ import annotations

from typing import Any

# the tuned parameters ("net_width": both hidden layers of pi and vf)
SPACE = ("n_envs", "n_steps", "batch_size", "n_epochs", "learning_rate", "net_width",
         "log_std_init", "gamma")


def sample(trial: Any, fixed: dict | None = None) -> dict:
    """The tuned parameters of ``trial`` (an ``optuna.Trial``), flat: ``fixed`` ones as given.
    ``batch_size`` is capped at the rollout (``n_envs * n_steps``); ``learning_rate`` is a
    linear decay ``lin_<value>`` as in the shipped configs."""
    fixed = check_fixed(fixed)
    draw = {
        "n_envs": lambda: 2 ** trial.suggest_int("n_envs_pow", 6, 8),           # 64-256
        "n_steps": lambda: 2 ** trial.suggest_int("n_steps_pow", 3, 6),         # 8-64
        "batch_size": lambda: 2 ** trial.suggest_int("batch_size_pow", 8, 11),  # 256-2048
        "n_epochs": lambda: trial.suggest_categorical("n_epochs", [5, 10, 20]),
        "learning_rate": lambda: "lin_{:.3g}".format(
            trial.suggest_float("learning_rate", 5e-5, 2e-3, log=True)),
        "net_width": lambda: trial.suggest_categorical("net_width", [64, 128, 256]),
        "log_std_init": lambda: trial.suggest_float("log_std_init", -2.0, 0.0),
        "gamma": lambda: 1.0 - trial.suggest_float("one_minus_gamma", 1e-3, 0.05, log=True),
    }
    flat = {k: fixed[k] if k in fixed else draw[k]() for k in SPACE}
    flat["batch_size"] = min(int(flat["batch_size"]), int(flat["n_envs"]) * int(flat["n_steps"]))
    return flat


# one point of the space (its smallest sizes, so that building it is quick): the trial that
# checks a command's settings before its study starts (agents.rl.tuning.tune.check_settings)
PROBE = {"n_envs_pow": 6, "n_steps_pow": 3, "batch_size_pow": 8, "n_epochs": 5,
         "learning_rate": 3e-4, "net_width": 64, "log_std_init": -1.0, "one_minus_gamma": 0.01}


# what a fixed value must be (by key; the rest are whole numbers >= 1)
MUST = {"learning_rate": "a rate > 0 or lin_<rate>", "log_std_init": "a finite number",
        "gamma": "in (0, 1]"}


def _fixed_ok(key: str, v: Any) -> bool:
    import math

    if key == "learning_rate" and isinstance(v, str) and v.startswith("lin_"):
        try:
            v = float(v[4:])
        except ValueError:
            return False
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        return False
    if key == "learning_rate":
        return v > 0
    if key == "gamma":
        return 0 < v <= 1
    return key == "log_std_init" or (isinstance(v, int) and v >= 1)


def check_fixed(fixed: dict | None) -> dict:
    """``fixed`` as a dict; ValueError for a key that is not a tuned parameter or a value that
    cannot be one (saying what it must be)."""
    fixed = dict(fixed or {})
    unknown = sorted(set(fixed) - set(SPACE))
    if unknown:
        raise ValueError(f"cannot fix {', '.join(unknown)}: the tuned parameters are "
                         f"{', '.join(SPACE)} (others come from the conf file)")
    for k, v in fixed.items():
        if not _fixed_ok(k, v):
            raise ValueError(f"{k} must be {MUST.get(k, 'a whole number >= 1')}, got {v!r}")
    return fixed


def overrides(base: dict, flat: dict) -> dict:
    """The hyperparameters to put over ``base`` (a parsed config entry, :func:`.hyperparams.load`)
    for the tuned values ``flat``: the net width into ``policy_kwargs`` (its other keys kept),
    gamma also into ``normalize`` (reward normalisation discounts as the agent does, as rl-zoo3
    sets it)."""
    out = {k: v for k, v in flat.items() if k not in ("net_width", "log_std_init")}
    w = int(flat["net_width"])
    out["policy_kwargs"] = {**(base.get("policy_kwargs") or {}),
                            "net_arch": {"pi": [w, w], "vf": [w, w]},
                            "log_std_init": float(flat["log_std_init"])}
    norm = base.get("normalize")
    if isinstance(norm, dict) and "gamma" in norm:
        out["normalize"] = {**norm, "gamma": float(flat["gamma"])}
    return out


def dict_text(d: dict) -> str:
    """``d`` as rl-zoo3 writes it in a config: ``dict(key=value, ...)`` (nested dicts alike,
    activation classes as ``nn.<Name>``), which :func:`.hyperparams.load` parses back."""
    def value(v: Any) -> str:
        if isinstance(v, dict):
            if all(isinstance(k, str) and k.isidentifier() for k in v):
                return dict_text(v)
            return "{" + ", ".join(f"{value(k)}: {value(x)}" for k, x in v.items()) + "}"
        if isinstance(v, type):
            return f"nn.{v.__name__}"
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        if isinstance(v, tuple):
            return "(" + ", ".join(value(x) for x in v) + ("," if len(v) == 1 else "") + ")"
        return repr(v)
    return "dict(" + ", ".join(f"{k}={value(v)}" for k, v in d.items()) + ")"


# entries a config writes as dict(...) strings (hyperparams.load parses them)
DICT_KEYS = ("policy_kwargs", "normalize", "replay_buffer_kwargs")


def config_yaml(env_id: str, hp: dict, comment: str = "") -> str:
    """An rl-zoo3 config file holding one entry, ``env_id: hp`` (``hp`` parsed, as
    :func:`.hyperparams.load` returns it), with ``comment`` lines on top; keys only this
    package reads go to the file's :data:`.hyperparams.PACKAGE_SECTION` section, so the file
    runs under ``python -m rl_zoo3.train`` as it is and :func:`.hyperparams.load` reads ``hp``
    back."""
    import yaml

    from ..training.hyperparams import PACKAGE_SECTION, split_package_keys

    zoo, package = split_package_keys(hp)
    entry = {k: dict_text(v) if k in DICT_KEYS and isinstance(v, dict) else v
             for k, v in zoo.items()}
    doc: dict = {env_id: entry}
    if package:
        doc[PACKAGE_SECTION] = {env_id: package}
    head = "".join(f"# {line}\n" for line in comment.splitlines())
    return head + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=100)
