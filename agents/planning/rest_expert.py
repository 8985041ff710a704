"""The core of the one-step experts of the scenes whose parts are fired from rest (the
positioner's :class:`agents.mpc.experts.BatchExpert`, the plane's
:class:`agents.planning.plane.PlaneController`): how a grid of candidate firings is ranked, which
of them are confirmed on the full model, and which one fires.

Every part has a grid of candidates: aims (actuators) x frequencies x strokes, ordered aim,
frequency, stroke. Each has an error [m] (inf: refused: it detaches, lies next to a refused
cell, runs past the time limit, or no aim exists). The rule:

* among the candidates within ``slack`` [m] of the part's nearest, the gentlest fires: the
  lowest frequency, then the smallest stroke, then the first aim (:func:`gentleness`): it lands
  as near, accelerates the part least and makes the answer change smoothly with the state,
  which a network imitating it needs (an argmin over the grid jumps between firings that land
  equally near); the others follow by error (:meth:`RestRanking.ordered`);
* ranked on a firing map, the ``confirm`` first in that order and the ``confirm`` nearest not
  among them are fired on the full model (:meth:`RestRanking.shortlist`), and the rule is
  applied again to the full model's answers alone;
* with a check on a heavier part, the first of the ``checked`` first in that order that the
  heavier part survives fires (:meth:`RestRanking.first_surviving`);
* a firing counts only if it brings the part closer by more than :data:`MIN_GAIN`.

Also the range checks of their settings (:func:`check_integers`, :func:`check_in`).
"""
from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

MIN_GAIN = 0.1e-6   # [m] a firing that brings the part less closer than this does not count


def check_integers(obj: Any, least: Iterable[tuple[str, int]]) -> None:
    """Each named field of ``obj`` is an integer (not a bool) at least its bound: else one
    ValueError naming it."""
    for name, lo in least:
        v = getattr(obj, name)
        if isinstance(v, bool) or not isinstance(v, int) or v < lo:
            raise ValueError(f"{name} = {v!r} is invalid: must be an integer >= {lo}")


def check_in(obj: Any, bounds: Iterable[tuple[str, float]]) -> None:
    """Each named field of ``obj`` is a number (not a bool) in ``[0, hi]``: else one ValueError
    naming it."""
    for name, hi in bounds:
        v = getattr(obj, name)
        if not (isinstance(v, (int, float)) and 0.0 <= v <= hi) or isinstance(v, bool):
            raise ValueError(f"{name} = {v!r} is invalid: must be in [0, {hi:g}]")


def gentleness(aims: int, frequencies: int, strokes: int) -> np.ndarray:
    """The gentleness rank of each candidate of a part's grid, ordered aim, frequency, stroke
    (flattened, ``aims * frequencies * strokes``): by frequency, then stroke, then aim."""
    f, h = frequencies, strokes
    return (np.arange(f)[None, :, None] * (h * aims) + np.arange(h)[None, None, :] * aims
            + np.arange(aims)[:, None, None]).ravel()


class RestRanking:
    """The rule of the module docstring on a grid of ``aims`` x ``frequencies`` x ``strokes``
    candidates per part, with ``slack`` [m] and ``confirm`` [-]."""

    def __init__(self, aims: int, frequencies: int, strokes: int, slack: float,
                 confirm: int) -> None:
        self.rank = gentleness(aims, frequencies, strokes)
        self.slack = slack
        self.confirm = confirm

    def ordered(self, err: np.ndarray, rank: np.ndarray) -> np.ndarray:
        """Each row's candidates (columns) in the expert's order: those within the slack of the
        row's nearest by ``rank`` (gentlest first), then the others by error ``err`` [m]."""
        least = err.min(axis=1, keepdims=True)
        by_err = np.argsort(np.argsort(err, axis=1, kind="stable"), axis=1)
        key = np.where(err <= least + self.slack, rank, rank.size + by_err)
        return np.argsort(key, axis=1, kind="stable")

    def shortlist(self, err: np.ndarray) -> np.ndarray:
        """The candidates ``(M, 2k)`` to confirm on the full model, of errors ``err`` ``(M,
        per)`` [m] on the map: the ``k = min(confirm, per)`` first in the expert's order and the
        ``k`` nearest not among them."""
        m, per = err.shape
        rows = np.arange(m)
        k = min(self.confirm, per)
        first = self.ordered(err, self.rank[None, :])[:, :k]
        taken = np.zeros((m, per), bool)
        taken[rows[:, None], first] = True
        near = np.argsort(err, axis=1, kind="stable")
        fresh = np.argsort(taken[rows[:, None], near], axis=1, kind="stable")[:, :k]
        return np.concatenate([first, near[rows[:, None], fresh]], axis=1)

    @staticmethod
    def first_surviving(order: np.ndarray, err: np.ndarray, checked: int,
                        survives: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        """Each row's choice: of its ``checked`` first columns in ``order`` (the expert's order
        of candidates of errors ``err`` [m]), the first one of finite error that
        ``survives(top)`` (bool, the shape of ``top``, the candidates' columns ``(M, kk)``)
        says a heavier part survives; the first in ``order`` where none does."""
        rows = np.arange(len(order))
        top = order[:, :min(checked, order.shape[1])]
        ok = survives(top) & np.isfinite(np.take_along_axis(err, top, axis=1))
        return np.where(ok.any(axis=1), top[rows, np.argmax(ok, axis=1)], order[:, 0])
