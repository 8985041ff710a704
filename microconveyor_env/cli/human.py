"""Human output of a result dict: SI values (unit-suffixed keys, as in JSON) shown in the units
people read (µm, mm, µN, nN, ms, %), nested dicts indented, short lists of records as tables,
long lists summarised.

``format_result({"median_abs_error_m": 6.4e-06, "success_rate": 0.97})`` gives::

    median_abs_error     6.40 µm
    success_rate         97.0 %

The contract of every command's output without ``--json`` (docs/cli.md, tested on every
command in tests/cli/test_every_command.py): text for people, never a Python repr (no ``{'``,
``['``, ``None``); every quantity with a unit in the units people read (a length in nm, µm or
mm, a force in nN or µN, a time in µs, ms or s, a rate in %), never a raw SI float such as
``6.94e-08`` or ``0.00015000000000000001``; micrometres written µm. Scientific notation is left
to dimensionless figures (relative errors, p-values).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

WIDTH = 30
MAX_LIST = 8     # longer lists are summarised: their length, first and last
MAX_DEPTH = 5    # nesting shown in full; deeper dicts are summarised by their keys


def _scaled(v: float, units: tuple[tuple[float, str], ...]) -> str:
    """``v`` in the first unit whose scale it reaches (the last unit otherwise)."""
    if v == 0 or not math.isfinite(v):
        return f"{v:g} {units[-1][1]}" if v == 0 else f"{v}"
    for scale, name in units:
        if abs(v) >= scale:
            return f"{v / scale:.4g} {name}"
    scale, name = units[-1]
    return f"{v / scale:.4g} {name}"


_LENGTH = ((1.0, "m"), (1e-3, "mm"), (1e-6, "µm"), (1e-9, "nm"))
_FORCE = ((1.0, "N"), (1e-3, "mN"), (1e-6, "µN"), (1e-9, "nN"), (1e-12, "pN"))
_TIME = ((1.0, "s"), (1e-3, "ms"), (1e-6, "µs"), (1e-9, "ns"))
# key suffix -> (formatter, shown name without the suffix); longest suffixes first
SUFFIXES: tuple[tuple[str, Callable[[float], str]], ...] = (
    ("_m_s2", lambda v: f"{v:.4g} m/s²"),
    ("_m_s", lambda v: f"{v:.4g} m/s"),
    ("_m2", lambda v: f"{v:.4g} m²"),
    ("_J_m2", lambda v: f"{v:.4g} J/m²"),
    ("_kg", lambda v: f"{v:.4g} kg"),
    ("_Pa", lambda v: f"{v:.4g} Pa"),
    ("_hz", lambda v: f"{v:.5g} Hz"),
    ("_Hz", lambda v: f"{v:.5g} Hz"),
    ("_per_s", lambda v: f"{v:.4g} /s"),
    ("_per_m2", lambda v: f"{v:.4g} /m²"),
    ("_m", lambda v: _scaled(v, _LENGTH)),
    ("_N", lambda v: _scaled(v, _FORCE)),
    ("_s", lambda v: _scaled(v, _TIME)),
    ("_rate", lambda v: f"{100 * v:.1f} %"),
)
for _tol in ("5um", "10um", "20um", "50um", "100um", "250um"):  # success_rate_5um, ... are rates
    SUFFIXES += ((f"_rate_{_tol}", lambda v: f"{100 * v:.1f} %"),)


def _unit_of(key: str) -> tuple[str, Callable[[float], str] | None]:
    for suffix, fmt in sorted(SUFFIXES, key=lambda s: -len(s[0])):
        if key.endswith(suffix):
            shown = key if suffix.startswith("_rate") else key[: -len(suffix)]
            return shown, fmt
    return key, None


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _records(v: Any) -> bool:
    return isinstance(v, (list, tuple)) and bool(v) and all(isinstance(x, dict) for x in v)


def format_value(key: str, v: Any) -> tuple[str, str]:
    """(shown key, shown value) of one entry."""
    shown, fmt = _unit_of(key)
    if _number(v):
        return shown, fmt(float(v)) if fmt else (f"{v:.6g}" if isinstance(v, float) else str(v))
    if isinstance(v, (list, tuple)) and v and all(_number(x) for x in v):
        items = [fmt(float(x)) if fmt else f"{x:.6g}" for x in v]
        if len(items) > MAX_LIST:
            return shown, f"{len(items)} values: {items[0]} ... {items[-1]}"
        return shown, "[" + ", ".join(items) + "]"
    if isinstance(v, (list, tuple)) and len(v) > MAX_LIST:
        return shown, f"{len(v)} entries (--json for all)"
    if isinstance(v, (list, tuple)) and v and all(isinstance(x, (list, tuple)) for x in v):
        return shown, ", ".join(format_value(key, x)[1] for x in v)   # e.g. a box's ranges
    if isinstance(v, (list, tuple)):
        return shown, ", ".join(format_value(key, x)[1] for x in v) if v else "none"
    if isinstance(v, dict):
        return shown, f"{', '.join(map(str, v))} (--json for the values)" if v else "none"
    if v is None:
        return shown, "none"
    return shown, str(v)


def format_table(rows: list[dict[str, Any]], indent: int = 0) -> str:
    """``rows`` (records with the same kind of keys) as aligned columns: a header of the shown
    keys, each cell in the units people read."""
    keys: list[str] = []
    for r in rows:
        keys += [k for k in map(str, r) if k not in keys]
    cells = [[format_value(k, r[k])[1] if k in r else "" for k in keys] for r in rows]
    head = [_unit_of(k)[0] for k in keys]
    widths = [max(len(h), *(len(c[i]) for c in cells)) for i, h in enumerate(head)]
    pad = "  " * indent
    return "\n".join(pad + "  ".join(f"{c:{w}s}" for c, w in zip(line, widths, strict=True)).rstrip()
                     for line in [head, *cells])


def format_result(result: dict[str, Any], indent: int = 0) -> str:
    """The lines of ``result`` for a terminal."""
    lines = []
    pad = "  " * indent
    for key, v in result.items():
        if isinstance(v, dict) and v:
            if indent + 1 >= MAX_DEPTH:
                lines.append(f"{pad}{key}: {format_value(str(key), v)[1]}")
            else:
                lines.append(f"{pad}{key}:")
                lines.append(format_result(v, indent + 1))
            continue
        if _records(v) and len(v) <= MAX_LIST:
            lines.append(f"{pad}{key}:")
            lines.append(format_table(list(v), indent + 1))
            continue
        shown, text = format_value(str(key), v)
        lines.append(f"{pad}{shown:{max(WIDTH - len(pad), 1)}s} {text}")
    return "\n".join(line for line in lines if line)
