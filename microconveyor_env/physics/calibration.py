"""Calibration of the KE contact law to measured values (docs/physics.md §2.6).

KE friction predictions are uncertain by orders of magnitude at this scale, so two measured values
can pin the model:

* a measured **pull-off force** fixes ``beta`` (all KE forces are proportional to ``eta A_n``, hence to
  ``beta``: the fit is exact, ``beta' = beta F_meas / F_pull(beta)``);
* a measured **friction force at a load** fixes ``friction_scale`` (a factor on Q), after beta:
  ``scale' = Q_meas / Q_KE(N_meas)``.

Both fits are closed form and leave the separations (balance, pull-off) unchanged.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from .contact_table import ContactTable
from .materials import ContactParams, check_range


@dataclass(frozen=True)
class Calibration:
    """Measured targets. ``friction_load`` [N] defaults to the part's weight ``m g0``."""

    pull_off_force: float | None = None      # [N]
    friction_force: float | None = None      # [N]
    friction_load: float | None = None       # [N]

    def __post_init__(self) -> None:
        if self.pull_off_force is not None:
            check_range("Calibration", "pull_off_force", self.pull_off_force, 0, math.inf, True,
                        unit="N")
        if self.friction_force is not None:
            check_range("Calibration", "friction_force", self.friction_force, 0, math.inf, True,
                        unit="N")
        if self.friction_load is not None:
            check_range("Calibration", "friction_load", self.friction_load, unit="N")
            if self.friction_force is None:
                raise ValueError("Calibration.friction_load given without friction_force")


def calibrate(params: ContactParams, target: Calibration,
              **table_kw: Any) -> tuple[ContactParams, dict[str, Any]]:
    """Fit ``beta`` and/or ``friction_scale`` to ``target``; return (new params, report).

    The report lists each fitted quantity with its value before and after and the target met
    (forces [N]; beta and friction_scale [-]). ``table_kw`` go to :class:`ContactTable`.
    """
    report: dict[str, Any] = {"fitted": []}
    if target.pull_off_force is not None:
        before = ContactTable(params, **table_kw).pull_off_force
        beta = params.surface.beta * target.pull_off_force / before
        report["beta"] = {"before": params.surface.beta, "after": beta,
                          "pull_off_force_before_N": before,
                          "pull_off_force_target_N": target.pull_off_force}
        report["fitted"].append("beta")
        params = params.replace(surface__beta=beta)
    if target.friction_force is not None:
        load = params.part.weight if target.friction_load is None else target.friction_load
        table = ContactTable(params, **table_kw)
        q = float(table.friction(load))  # raises DetachmentError for a load below -F_pull
        scale = params.friction_scale * target.friction_force / q
        report["friction_scale"] = {"before": params.friction_scale, "after": scale,
                                    "load_N": load, "friction_before_N": q,
                                    "friction_target_N": target.friction_force}
        report["fitted"].append("friction_scale")
        params = params.replace(friction_scale=scale)
    return params, report
