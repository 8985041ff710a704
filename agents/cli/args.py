"""Argument parsers the agents' commands share (argparse ``type=`` callables)."""
from __future__ import annotations

import argparse
import math
from pathlib import Path


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


def folder(text: str) -> str:
    """A folder for output files (created later if missing); not an existing file."""
    p = Path(text)
    if not text.strip():
        raise argparse.ArgumentTypeError("empty folder name")
    if p.exists() and not p.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r} is a file; give a folder for the charts")
    return str(p)


def minutes(text: str) -> float:
    """A wall-time budget [min]: a positive finite number."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of minutes") from None
    if not math.isfinite(v) or v <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive finite number of minutes, got {text}")
    return v
