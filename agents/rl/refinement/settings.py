"""The settings of a refinement (:mod:`.refine`), validated once."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class RefineSettings:
    """``targets`` [-] training targets per round; ``rounds`` [-] correct-and-fit rounds;
    ``newton_iterations`` [-] on the last firing, ``first_iterations`` [-] on the first firing
    alone, per round; ``step`` [action units] forward-difference step;
    ``max_step`` [action units] largest Newton step; ``accept_m`` [m] a corrected episode is kept
    when it ends this close; ``fit_iterations`` [-] L-BFGS iterations per fit; ``seed`` [-] of the
    training targets."""

    targets: int = field(default=1000, metadata={
        "help": "training targets per round, drawn from the policy's target range (default "
                "{default})", "bounds": (1, None)})
    rounds: int = field(default=8, metadata={"help": "correct-and-fit rounds (default {default})",
                                             "bounds": (1, None)})
    newton_iterations: int = 6
    first_iterations: int = 12
    step: float = 1e-3
    max_step: float = 0.2
    accept_m: float = 10e-6
    fit_iterations: int = field(default=1000, metadata={
        "help": "L-BFGS iterations of each fit (default {default})", "bounds": (1, None)})
    seed: int = field(default=0, metadata={"help": "seed of the training targets (default {default})"})

    def __post_init__(self) -> None:
        for name in ("targets", "rounds", "newton_iterations", "first_iterations",
                     "fit_iterations"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < 1:
                raise ValueError(f"refine: {name} must be an integer >= 1, got {value!r}")
        for name in ("step", "max_step", "accept_m"):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0:
                raise ValueError(f"refine: {name} must be a positive number, got {value!r}")
