"""Why this model does not reproduce the dissertation's Table 4.3: one-at-a-time model changes.

The dissertation's optimum (719 Hz, 500 µm spacing, 1 ms delay, 178 µm stroke) carries its part
to 10.02 mm in 0.037 s; here it rests at 0.067 mm. :func:`explain` replays that schedule under
single changes of the model (integrator, kinematics level, bump shape and width, friction scale,
pull-off force, start position, mass) and a few pairs, and (optionally) re-runs the
dissertation's DE under each change to see what the shared-parameter problem reaches there.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from microconveyor_env.physics.calibration import Calibration, calibrate
from microconveyor_env.physics.materials import ContactParams

from .dissertation import TABLE_4_3, DissertationProblem, evaluate_parameters, solve_dissertation

Change = Callable[[DissertationProblem, ContactParams], DissertationProblem]


def _friction(k: float) -> Change:
    return lambda p, c: p.replace(contact=c.replace(friction_scale=c.friction_scale * k))


def _pull_off(force: float) -> Change:
    # beta refitted to the pull-off force, then the friction scale refitted to Q(m g0) = 8e-8 N
    def change(p: DissertationProblem, c: ContactParams) -> DissertationProblem:
        fitted, _ = calibrate(c, Calibration(pull_off_force=force, friction_force=8e-8))
        return p.replace(contact=fitted)
    return change


def _config(**kw: Any) -> Change:
    return lambda p, c: p.replace(**{f"config__{k}": v for k, v in kw.items()})


def _both(a: Change, b: Change) -> Change:
    def change(p: DissertationProblem, c: ContactParams) -> DissertationProblem:
        q = a(p, c)
        return b(q, q.contact or c)
    return change


# (label, change): the model as shipped first; SI values in the labels
VARIANTS: list[tuple[str, Change]] = [
    ("as shipped (event, reduced, Gaussian WL 0.6 mm, start 0.15 mm)", lambda p, c: p),
    ("Karnopp integrator (the dissertation's)", _config(mode="karnopp")),
    ("exact kinematics", _config(kinematics="exact")),
    ("sinusoidal bump", _config(shape="sinusoidal")),
    ("clamped-beam bump", _config(shape="clamped_beam")),
    ("Gaussian WL 0.8 mm (s = 133 µm)", _config(wavelength=0.8e-3)),
    ("Gaussian WL 1.0 mm (s = 167 µm)", _config(wavelength=1.0e-3)),
    ("Gaussian WL 1.2 mm (s = 200 µm)", _config(wavelength=1.2e-3)),
    ("friction x 0.5", _friction(0.5)),
    ("friction x 0.25", _friction(0.25)),
    ("friction x 0.1", _friction(0.1)),
    ("friction x 0.015", _friction(0.015)),
    ("pull-off 3.1e-6 N (half)", _pull_off(3.1e-6)),
    ("pull-off 1.24e-5 N (double)", _pull_off(1.24e-5)),
    ("start 0.10 mm upstream", _config(start_offset=0.10e-3)),
    ("start 0.06 mm upstream", _config(start_offset=0.06e-3)),
    ("mass 1e-9 kg", lambda p, c: p.replace(contact=c.replace(part__mass=1e-9))),
    ("mass 4e-9 kg", lambda p, c: p.replace(contact=c.replace(part__mass=4e-9))),
    ("pair: WL 0.95 mm and friction x 0.25", _both(_config(wavelength=0.95e-3),
                                                   _friction(0.25))),
    ("pair: WL 1.0 mm and friction x 0.3", _both(_config(wavelength=1.0e-3), _friction(0.3))),
]


def explain(problem: DissertationProblem | None = None, reoptimize: bool = True, seed: int = 0,
            params: dict[str, float] | None = None,
            variants: list[tuple[str, Change]] | None = None,
            progress: Callable[[dict[str, Any]], None] | None = None) -> list[dict[str, Any]]:
    """One row per variant: the Table 4.3 schedule (or ``params``) replayed under it
    (``table43_*``: final position [m], travel time [s], outcome) and, with ``reoptimize``, the
    dissertation's DE (seed ``seed``, 2,550 episodes) under it (``de_*``); ``progress(row)``
    after each row."""
    base = problem or DissertationProblem()
    contact = base.simulator().contact
    rows = []
    for label, change in variants or VARIANTS:
        t0 = time.perf_counter()
        prob = change(base, contact)
        rep = evaluate_parameters(params or TABLE_4_3, prob)
        row: dict[str, Any] = {"variant": label,
                               "table43_final_position_m": rep["final_position_m"],
                               "table43_travel_time_s": rep["travel_time_s"],
                               "table43_outcome": rep["outcome"]}
        if reoptimize:
            res = solve_dissertation("de", seed=seed, problem=prob)
            row.update(de_parameters=res.parameters, de_final_position_m=res.final_position_m,
                       de_travel_time_s=res.travel_time_s, de_outcome=res.outcome,
                       de_cost=res.cost)
        row["wall_time_s"] = time.perf_counter() - t0
        rows.append(row)
        if progress:
            progress(row)
    return rows
