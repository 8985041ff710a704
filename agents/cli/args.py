"""Argument parsers the agents' commands share (argparse ``type=`` callables)."""
from __future__ import annotations

import argparse
import ast
import math
from typing import Any

from microconveyor_env.env_ids import DEFAULT_ENV_ID


def floats(text: str) -> list[float]:
    """A list of numbers: ``lo:hi:step`` (inclusive of ``hi``) or a comma list."""
    try:
        if ":" in text:
            lo, hi, step = (float(v) for v in text.split(":"))
            if not step > 0 or hi < lo:
                raise ValueError
            import numpy as np

            return [float(v) for v in np.arange(lo, hi + step / 2, step)]
        vals = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give lo:hi:step (step > 0) or a comma "
                                         "list of numbers") from None
    if not vals or not all(math.isfinite(v) for v in vals):
        raise argparse.ArgumentTypeError(f"{text!r}: give at least one finite number")
    return vals


def levels(text: str) -> list[float]:
    """Perturbation levels: :func:`floats`, each >= 0."""
    vals = floats(text)
    if min(vals) < 0:
        raise argparse.ArgumentTypeError(f"{text!r}: levels must be >= 0")
    return vals


def budgets(text: str) -> list[int]:
    """Episode budgets: a comma list of integers >= 10, sorted, without repeats."""
    try:
        vals = [int(float(v)) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give a comma list of integers") from None
    if not vals or min(vals) < 10:
        raise argparse.ArgumentTypeError(f"{text!r}: budgets must be integers >= 10 episodes")
    return sorted(set(vals))


def level(text: str) -> float:
    """One perturbation level: a finite number >= 0 (:func:`levels`, one value)."""
    vals = levels(text)
    if len(vals) != 1:
        raise argparse.ArgumentTypeError(f"{text!r}: give one number")
    return vals[0]


def minutes(text: str) -> float:
    """A wall-time budget [min]: a positive finite number."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of minutes") from None
    if not math.isfinite(v) or v <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive finite number of minutes, got {text}")
    return v


_WORDS = {"true": True, "false": False, "null": None, "none": None}


def env_kwarg(text: str) -> tuple[str, Any]:
    """One ``KEY:VALUE`` of ``--env-kwargs`` (rl-zoo3's form): the value a Python literal
    (``5``, ``0.5e-3``, ``(0.5e-3, 6e-3)``, ``[1, 2]``, ``True``), ``true``/``false``/``null``,
    or else a plain string (``preset:conveyor``). Parsed as data, never evaluated."""
    key, sep, raw = text.partition(":")
    key, raw = key.strip(), raw.strip()
    if not sep or not key.isidentifier() or not raw:
        raise argparse.ArgumentTypeError(f"{text!r}: give KEY:VALUE, e.g. n_actuators:7 or "
                                         "'target_range:(0.5e-3, 6e-3)'")
    if raw.lower() in _WORDS:
        return key, _WORDS[raw.lower()]
    try:
        value = ast.literal_eval(raw)
    except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):
        value = raw
    return key, list(value) if isinstance(value, tuple) else value


class _EnvPreset(argparse.Action):
    """``--preset NAME``: the env's preset, appended to ``--env-kwargs`` as ``preset:NAME`` (so
    everything that reads the env kwargs, a policy's scene check included, sees it)."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: Any, option_string: str | None = None) -> None:
        items = list(getattr(namespace, self.dest, None) or [])
        items.append(("preset", values))
        setattr(namespace, self.dest, items)


def add_env_args(p: argparse.ArgumentParser, default: str | None = DEFAULT_ENV_ID,
                 what: str = "", default_text: str | None = None) -> None:
    """``--env ID`` (any registered id: a command that cannot use one refuses it in one line
    when it runs), ``--env-kwargs KEY:VALUE ...`` (its overrides,
    as ``gym.make(ID, **kwargs)``; repeated, the lists add up) and ``--preset NAME`` (the env's
    surface: ``--env-kwargs preset:NAME``); ``default_text`` says what a ``None`` default
    means."""
    from microconveyor_env.cli.base import PRESET_HELP, preset_name
    from microconveyor_env.env_ids import ALL_ENV_IDS

    p.add_argument("--env", choices=ALL_ENV_IDS,
                   default=default,
                   help=f"env id{what} (default: {default or default_text})")
    p.add_argument("--env-kwargs", type=env_kwarg, nargs="+", action="extend", default=None,
                   metavar="KEY:VALUE",
                   help="env overrides as gym.make(ID, **kwargs): SI units, e.g. n_actuators:7 "
                        "'target_range:(0.5e-3, 6e-3)'")
    p.add_argument("--preset", type=preset_name, action=_EnvPreset, dest="env_kwargs",
                   metavar="NAME", help="the env's surface, as --env-kwargs preset:NAME (default: "
                                        f"the env's own): {PRESET_HELP}")


def line_env(env_id: str, command: str) -> str:
    """``env_id`` if it is an env of the line (one axis: MicroConveyor-v0, -v1 and the goal
    variant), else a ValueError saying that ``command`` works on the line only."""
    from microconveyor_env.env_ids import REGISTRY

    reg = REGISTRY[env_id]
    if reg.geometry != "line":
        lines = ", ".join(i for i, r in REGISTRY.items() if r.geometry == "line")
        raise ValueError(f"{command} works on the line's envs ({lines}); {env_id} is the "
                         f"{reg.geometry}, a scene it does not handle")
    return env_id


def env_kwargs_of(args: argparse.Namespace) -> dict[str, Any]:
    """``--env-kwargs`` (with ``--preset``) as a dict (a key given twice is an error)."""
    out: dict[str, Any] = {}
    for key, value in args.env_kwargs or []:
        if key in out:
            raise ValueError(f"--env-kwargs/--preset: {key} given twice")
        out[key] = value
    return out


def target_point(text: str) -> list[float]:
    """A target [m]: one number (a distance along a line) or ``X,Y`` (a point of the plane),
    each finite."""
    try:
        vals = [float(v) for v in text.split(",")]
    except ValueError:
        vals = []
    if len(vals) not in (1, 2) or not all(math.isfinite(v) for v in vals):
        raise argparse.ArgumentTypeError(f"{text!r}: give a target in m, one number (e.g. 7.5e-3) "
                                         "or X,Y on the plane (e.g. 1.5e-3,0.5e-3)")
    return vals


def scene_config_of(args: argparse.Namespace, default: str = DEFAULT_ENV_ID,
                    **fixed: Any) -> Any:
    """The config of ``--env`` (``default`` if not given) with ``--env-kwargs``, then ``fixed``,
    of any registered id: the line's EnvConfig, the positioner's or the plane's config."""
    from microconveyor_env.envs.core.versions import scene_config

    return scene_config(args.env or default, **{**env_kwargs_of(args), **fixed})


def env_config_of(args: argparse.Namespace, default: str = DEFAULT_ENV_ID,
                  **fixed: Any) -> Any:
    """The EnvConfig of ``--env`` (``default`` if not given) with ``--env-kwargs``, then
    ``fixed`` (a command's own overrides, e.g. reach's target range)."""
    from microconveyor_env.envs import env_config

    return env_config(args.env or default, **{**env_kwargs_of(args), **fixed})
