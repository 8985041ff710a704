"""Convergence of the plane's integrator as the step shrinks (docs/physics.md §10.5): the final
position of genuinely 2-D scenes (curved paths, stick-slip, stops sideways) against a fine-step
reference. A coarse ladder runs by default; the full study is ``-m slow``.

Helpers and scenes: ``tests/support/plane.py``. Measured numbers are printed (``pytest -s``).
"""
from __future__ import annotations

import functools

import numpy as np
import pytest

from support.plane import distance, quiet, scene, steps_sim


def _final(name, n, kinematics="reduced"):
    sched, start = scene(name)
    fmax = max(f.frequency for f in sched.firings)
    return quiet(steps_sim(fmax, n, kinematics=kinematics).simulate, sched, *start)


@functools.cache
def study(name, ladder, ref_steps, kinematics="reduced"):
    ref = _final(name, ref_steps, kinematics)
    errs = np.array([distance(_final(name, n, kinematics).final_position_m,
                              ref.final_position_m) for n in ladder])
    return ref, errs


def _order(ladder, errs):
    """Least-squares p in err ~ C dt^p (dt ~ 1/n)."""
    return float(np.polyfit(np.log(1.0 / np.asarray(ladder, float)), np.log(errs), 1)[0])


@pytest.mark.parametrize("name", ["pass_by", "relay"])
def test_coarse_convergence_order(name):
    """16 to 128 steps per (fastest) stroke against 2048: fitted order >= 3 (RK4 with located
    events; measured 3.1 for ``relay`` and 5.4 for ``pass_by``, whose path is smooth)."""
    ladder = (16, 32, 64, 128)
    ref, errs = study(name, ladder, 2048)
    order = _order(ladder, errs)
    print(f"\n{name} ({ref.outcome}, {ref.events} events): errors {errs} m, local orders "
          f"{np.round(np.log2(errs[:-1] / errs[1:]), 2)}, fitted order {order:.2f}")
    assert ref.outcome == "rest" and order >= 3.0
    assert errs[-1] < 1e-9


@pytest.mark.slow
@pytest.mark.parametrize("name,kinematics,min_order,finest", [
    ("pass_by", "reduced", 4.0, 1e-13), ("pass_by", "exact", 4.0, 1e-12),
    ("relay", "reduced", 3.0, 1e-12), ("relay", "exact", 1.2, 1e-11),
    ("oblique_stop", "reduced", 2.0, 2e-12), ("oblique_stop", "exact", 2.0, 2e-12)])
def test_convergence_study(name, kinematics, min_order, finest):
    """16 to 1024 steps per stroke against 32768, both kinematics levels. Measured fitted orders:
    ``pass_by`` 4.9 / 4.6 (smooth curved path), ``relay`` 3.7 (reduced) and 1.4 for its exact
    kinematics, which detaches (as in 1-D, the load's square-root approach to pull-off slows the
    detachment's convergence, tests/physics/test_dynamics_convergence.py), ``oblique_stop`` 2.5 /
    2.8 with a floor of ~1e-12 m: its stops happen at low speed, where the friction direction is
    held for a step and a stop is accepted within STOP_TOLERANCE (docs/physics.md §10.5)."""
    ladder = (16, 32, 64, 128, 256, 512, 1024)
    ref, errs = study(name, ladder, 32768, kinematics)
    errs = np.maximum(errs, 1e-16)
    order = _order(ladder, errs)
    print(f"\n{name}/{kinematics} ({ref.outcome}, {ref.events} events): errors {errs} m, local "
          f"orders {np.round(np.log2(errs[:-1] / errs[1:]), 2)}, fitted order {order:.2f}")
    assert order >= min_order and errs[-1] < finest
