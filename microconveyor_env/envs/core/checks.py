"""Checks every scene's envs apply to what a user passes: actions, reset options, render modes,
configs; the id an env was made with."""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt


def check_actions(actions: npt.ArrayLike, n: int | None, out: np.ndarray | None = None,
                  components: Sequence[str] = ("frequency", "stroke", "delay")) -> np.ndarray:
    """float64 ``(n, k)`` copy of the actions, checked (written into ``out``, a float64
    ``(n, k)`` array, when given, and returned); ``k`` is the number of ``components`` (named in
    messages).

    ``n = None`` is the single env: exactly shape ``(k,)``; otherwise exactly ``(n, k)``. A wrong
    shape, a non-numeric dtype (bool, complex, str, object) or NaN/inf raise ``ValueError``
    (values outside [-1, 1] are clipped when decoded). Every step calls it: the messages are
    only built when one is needed.
    """
    k = len(components)
    expected = (k,) if n is None else (n, k)
    try:
        raw = np.asarray(actions)
    except (TypeError, ValueError) as exc:  # ragged nested sequences
        raise ValueError(f"expected {_what(n, components)}, shape {expected}; got "
                         f"{type(actions).__name__} that is not an array ({exc})") from None
    if raw.shape != expected:
        raise ValueError(f"expected {_what(n, components)}, shape {expected}; got shape "
                         f"{raw.shape}")
    if raw.dtype.kind not in "iuf":
        raise ValueError(f"expected {_what(n, components)} as real numbers; got dtype "
                         f"{raw.dtype}")
    if out is None:
        a = raw.astype(np.float64).reshape(-1, k)
    else:
        a = out
        a[...] = raw.reshape(-1, k)  # the cast astype would do
    if not np.isfinite(a).all():
        raise ValueError(f"action contains NaN or inf: {a.tolist()}")
    return a


def _what(n: int | None, components: Sequence[str]) -> str:
    k, names = len(components), ", ".join(components)
    return (f"one action of {k} components ({names})" if n is None else
            f"{n} actions of {k} components ({names})")


# the keys of ``reset(options=...)`` every env of every scene knows
RESET_OPTIONS = ("state", "target")


def check_reset_options(options: object) -> dict[str, Any]:
    """``options`` of ``reset`` as a dict (None: empty), refused in one ValueError naming the
    known keys when it is not a mapping or holds a key no env reads: a misspelled option would
    otherwise be ignored and the episode drawn at random."""
    if options is None:
        return {}
    if not isinstance(options, Mapping):
        raise ValueError(f"reset options must be a dict with the keys {list(RESET_OPTIONS)}, "
                         f"got {type(options).__name__}")
    unknown = sorted((k for k in options if k not in RESET_OPTIONS), key=repr)
    if unknown:
        raise ValueError(f"reset options: unknown keys {unknown} (known keys: "
                         f"{list(RESET_OPTIONS)})")
    return dict(options)


def check_render_mode(render_mode: str | None, supported: Sequence[str]) -> None:
    """ValueError unless ``render_mode`` is None or one of ``supported``."""
    if render_mode is not None and render_mode not in supported:
        hint = "" if "human" in supported else (" (a window: the single env's render_mode "
                                                 "'human', with the render extra)")
        raise ValueError(f"render_mode {render_mode!r} not supported; use None or one of "
                         f"{list(supported)}{hint}")


def config_of(cls: Any, config: Any, kwargs: dict[str, Any]) -> Any:
    """An env's config: ``config`` (which must be a ``cls``) or ``cls.from_yaml(**kwargs)``
    (its defaults file, then the keyword overrides), not both."""
    if config is not None and kwargs:
        raise ValueError("give either config= or keyword overrides, not both")
    if config is not None and not isinstance(config, cls):
        article = "an" if cls.__name__[0] in "AEIOU" else "a"
        raise ValueError(f"config must be {article} {cls.__name__}, got {type(config).__name__}")
    return config or cls.from_yaml(**kwargs)


def spec_id(env: Any) -> str | None:
    """The registered id ``env`` was made with (``gym.make``, ``make_vec``); None without."""
    spec = getattr(env, "spec", None)
    return None if spec is None else str(spec.id)
