"""A part's saved state, the part every scene shares: naming where it was saved, its dict form,
the bound checks and the reset option that starts an episode from it.

A scene's state (the line's :class:`~..line.part_state.PartState`, the plane's
:class:`~..plane.part_state.PlaneState`) is a frozen dataclass subclassing :class:`SavedState`:
its own fields (SI units) first, then ``env_id`` (the registered id the env was made with, None
for an env made without ``gym.make``) and ``scene`` (the env's config fields that are its scene,
:func:`~.versions.scene_of`). ``env.get_state()`` returns it after any step and
``env.reset(options={"state": s})`` continues the episode from it, bit for bit.

As data it is a plain JSON-safe dict of SI numbers with unit-suffixed keys
(:meth:`SavedState.to_dict`, :meth:`SavedState.from_dict`). An env refuses a state saved in
another scene in one line naming the fields that differ (:func:`check_scene`): a position or a
firing count means something else with other actuators, surfaces or time limits. It refuses a
state saved in another env id too, naming both (:func:`check_saved_in`), even one of the same
scene (an interface variant, or an id made with overrides that give another id's scene): the
label and the scene must agree, so an edited or mixed-up state is never taken. An env made
without an id (``env_id`` None) and a state saved in one check the scene alone. A dict without
``env_id`` and ``scene`` is refused too, saying how to go on: nothing can check it, and a state
taken into the wrong scene runs without error and silently means something else. A state built
in code without a scene (as a controller builds the state it observed) is taken as the env's
own: the code that built it vouches for it.

The bounds every scene checks (:func:`within`, :func:`check_fired`, :func:`max_speed`): a firing
left, the episode's time not spent, a speed the part can reach (``v_max = 2 (15/4) h f +
sqrt(2 g h)``, with ``h``, ``f`` the top of the scene's ``stroke_range`` and ``freq_range``: the
surface moves vertically only and drives the part, its fastest point moving at the quintic
stroke's peak speed (15/4) h f; twice that, plus the speed of a slide down the highest bump,
bounds the part) and a position within ``v_max * max_time`` of the start.
"""
from __future__ import annotations

import dataclasses
import math
import numbers
from typing import Any, ClassVar, TypeVar

import numpy as np

from ...physics.materials import G0
from .versions import scene_of

S = TypeVar("S", bound="SavedState")
SAVED_IN = ("env_id", "scene")


class SavedState:
    """The base of a scene's saved part state (a frozen dataclass whose last fields are
    ``env_id`` and ``scene``). ``REQUIRED``: the fields a dict must have; ``NESTED``: the fields
    held as tuples (lists in the dict form)."""

    REQUIRED: ClassVar[tuple[str, ...]]
    NESTED: ClassVar[tuple[str, ...]] = ()
    env_id: str | None
    scene: dict[str, Any] | None

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        """Every field, in order (``env_id`` and ``scene`` last)."""
        return tuple(f.name for f in dataclasses.fields(cls))  # type: ignore[arg-type]

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict (the optional fields only when set; ``env_id`` and ``scene`` when the
        state names its scene)."""
        d: dict[str, Any] = {}
        for k in self.field_names():
            val = getattr(self, k)
            if k in SAVED_IN or (val is None and k not in self.REQUIRED):
                continue
            d[k] = _lists(val) if k in self.NESTED else val
        if self.scene is not None:
            d["env_id"], d["scene"] = self.env_id, dict(self.scene)
        return d

    @classmethod
    def from_dict(cls: type[S], d: dict[str, Any]) -> S:
        """The state a dict of :meth:`to_dict` describes (unknown or missing keys refused, a dict
        without ``env_id`` and ``scene`` too: module docstring)."""
        if not isinstance(d, dict):
            raise ValueError(f"a part state must be a dict or {cls.__name__}, got "
                             f"{type(d).__name__}")
        names = cls.field_names()
        unknown = sorted(set(d) - set(names))
        missing = [k for k in cls.REQUIRED if k not in d]
        if unknown or missing:
            raise ValueError(f"part state: unknown keys {unknown}, missing keys {missing} "
                             f"(keys: {list(names)})")
        if any(k not in d for k in SAVED_IN):
            raise ValueError("part state names no env id and scene (keys 'env_id', 'scene'; a "
                             "state saved before states named them), so it cannot be checked "
                             "against this env's scene: save it again with "
                             "env.get_state().to_dict(), or, if it is this env's, start from "
                             f"it in code: {cls.__name__}(**d)")
        scene = d["scene"]
        if not isinstance(scene, dict):
            raise ValueError(f"part state scene = {scene!r} is invalid: must be a mapping of "
                             "the env config's scene fields")
        nested = {k: None if d.get(k) is None else _tuples(d[k]) for k in cls.NESTED if k in d}
        return cls(**{**d, **nested, "scene": dict(scene)})


def _lists(v: Any) -> Any:
    return [_lists(x) for x in v] if isinstance(v, (tuple, list)) else v


def _tuples(v: Any) -> Any:
    return tuple(_tuples(x) for x in v) if isinstance(v, (tuple, list)) else v


def max_speed(config: Any) -> float:
    """The fastest a part can move in ``config``'s scene [m/s] (module docstring)."""
    h, f = config.stroke_range[1], config.freq_range[1]
    return 2.0 * 3.75 * h * f + math.sqrt(2.0 * G0 * h)


def within(name: str, value: object, lo: float, hi: float, unit: str, scale: float,
           why: str, hi_open: bool = False) -> float:
    """``value`` as a float if it is a finite real number in [lo, hi] (SI; ``hi_open``: below
    hi), else a one-line ValueError naming ``name``, the value and the range in ``unit`` (SI
    times ``scale``)."""
    x = math.nan
    if isinstance(value, (numbers.Real, np.floating, np.integer)) and not isinstance(
            value, (bool, np.bool_)):
        x = float(value)
    if math.isfinite(x) and lo <= x <= hi and not (hi_open and x == hi):
        return x
    u = f" {unit}" if unit else ""
    shown = repr(value) if math.isnan(x) and not isinstance(value, float) else repr(x)
    if scale != 1.0 and math.isfinite(x):
        shown += f" ({x * scale:.6g}{u})"
    allowed = (f"±{hi * scale:.6g}" if lo == -hi else
               f"[{lo * scale:.6g}, {hi * scale:.6g}{')' if hi_open else ']'}")
    raise ValueError(f"part state {name} = {shown} is invalid: must be finite and within "
                     f"{allowed}{u} ({why})")


def check_fired(fired: object, n: int) -> int:
    """``fired`` as an int if it is an integer in [0, n - 1] (``n`` firings an episode: one
    must be left), else a one-line ValueError."""
    if (isinstance(fired, (bool, np.bool_)) or not isinstance(fired, numbers.Integral)
            or not 0 <= int(fired) < n):
        raise ValueError(f"part state fired = {fired!r} is invalid: must be an integer in "
                         f"[0, {n - 1}] (a firing must be left)")
    return int(fired)


def check_time(time_s: object, config: Any) -> float:
    """``time_s`` [s] within [0, ``max_time``): the episode's time is not spent."""
    return within("time_s", time_s, 0.0, config.max_time, "ms", 1e3, "the episode's max_time",
                  hi_open=True)


def check_scene(state: SavedState, config: Any) -> None:
    """A one-line ValueError if ``state`` was saved in another scene than ``config``'s, naming
    the fields that differ (saved, here)."""
    env_id, saved = state.env_id, state.scene
    if env_id is not None and not isinstance(env_id, str):
        raise ValueError(f"part state env_id = {env_id!r} is invalid: must be an env id or null")
    here = scene_of(config)
    absent = "(absent)"

    def plain(v: Any) -> Any:
        return list(v) if isinstance(v, tuple) else v

    saved = {k: plain(v) for k, v in (saved or {}).items()}
    diff = [f"{k}: saved {saved.get(k, absent)!r}, here {here.get(k, absent)!r}"
            for k in sorted(set(saved) | set(here))
            if saved.get(k, absent) != here.get(k, absent)]
    if diff:
        where = env_id or "an env made without an id"
        raise ValueError(f"part state saved in {where} is of another scene than this env's: "
                         f"{'; '.join(diff)} (a state starts an episode only in its own scene; "
                         "randomisation and runtime knobs may differ)")


def check_saved_in(state: SavedState, env_id: str | None) -> None:
    """A one-line ValueError if ``state`` names an env id other than ``env_id`` (the id of the
    env it starts an episode in); a state or an env without an id passes (its scene is checked:
    :func:`check_scene`)."""
    saved = state.env_id
    if saved is not None and env_id is not None and saved != env_id:
        raise ValueError(f"part state saved in {saved} cannot start an episode in {env_id}: a "
                         "state starts an episode only in the env id it was saved in")


def reset_state(options: dict[str, Any] | None) -> Any:
    """The ``"state"`` of reset ``options`` (None without one); refuses it beside a ``"target"``
    (the state holds its target)."""
    if not options or options.get("state") is None:
        return None
    if "target" in options:
        raise ValueError("reset options: give 'state' (which holds its target) or 'target', "
                         "not both")
    return options["state"]
