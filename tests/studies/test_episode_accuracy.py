"""Episode-level accuracy of the env's default integrator (studies/episodes.py) and the kernel
changes it rests on: detachments hidden inside a step, strokes cut at max_time."""
import json

import numpy as np
import pytest

from microconveyor_env.envs import EnvConfig
from microconveyor_env.envs.core import actions
from microconveyor_env.physics.schedule import Schedule
from microconveyor_env.studies.episodes import compare, episode_study, run_episodes

from support import DATA as DATA_DIR
from support.dynamics import sim

DATA = json.loads((DATA_DIR / "episodes.json").read_text())
REFERENCE = {"mode": "event", "dt": 1e-7}
BAR = EnvConfig.from_yaml().tolerance / 10  # 5 um


def _stored():
    cfg = EnvConfig.from_yaml()
    acts = np.stack([actions.encode_actions(e["frequency_hz"], e["stroke_m"], e["delay_s"], cfg)
                     for e in DATA["episodes"]]).astype(np.float64)
    tail = np.array([e.get("tail", False) for e in DATA["episodes"]])
    return acts, tail


@pytest.fixture(scope="module")
def stored_runs():
    acts, tail = _stored()
    ref = run_episodes(acts, **REFERENCE)
    return acts, tail, ref


def test_stored_episodes_agree_with_the_converged_reference_at_the_default(stored_runs):
    """Every stored episode (a far throw, high-speed engagements, near-detachment cases) ends
    where the converged reference ends: same outcome, within tolerance/10; the two tail cases
    (the study's worst 1 %, where the far throw amplifies the error) within tolerance/2."""
    acts, tail, ref = stored_runs
    run = run_episodes(acts)
    assert (run["outcome"] == ref["outcome"]).all()
    err = np.abs(run["final_position_m"] - ref["final_position_m"])
    print(f"\nerrors at the default [um]: {np.round(err * 1e6, 3)}")
    assert (err[~tail] <= BAR).all()
    assert (err[tail] <= 5 * BAR).all()


def test_the_stored_set_tells_a_poor_setting_apart(stored_runs):
    """The former default (dt = 5e-5 s, >= 20 steps per stroke) misses the far throws by more
    than the bar: the stored episodes are discriminating, not easy."""
    acts, _, ref = stored_runs
    old = run_episodes(acts, dt=5e-5, min_steps=20)
    err = np.abs(old["final_position_m"] - ref["final_position_m"])
    assert np.nanmax(err) > 10 * BAR


def test_reference_is_converged(stored_runs):
    """Halving the reference step moves no final position by more than 0.1 um."""
    acts, _, ref = stored_runs
    half = run_episodes(acts, mode="event", dt=REFERENCE["dt"] / 2)
    c = compare(ref, half)
    assert c["outcome_disagreements"] == 0 and c["max_error_m"] <= 1e-7


def test_detachment_inside_one_step_is_found():
    """A 1611 Hz stroke pulls the part off between two grid points of a coarse step (the load's
    minimum moves with the part); the event mode finds it where a fine step does."""
    sched = Schedule.single(1611.465271, 163.7766e-6)
    coarse = sim(dt=5e-5, min_steps=20).simulate(sched, -0.15e-3)
    fine = sim(dt=1e-7, min_steps=20).simulate(sched, -0.15e-3)
    assert fine.outcome == coarse.outcome == "detached"
    assert abs(coarse.detach_time_s - fine.detach_time_s) < 1e-8
    assert abs(coarse.detach_position_m - fine.detach_position_m) < 1e-8


def test_max_time_cuts_a_stroke():
    """A stroke longer than max_time ends at max_time with outcome max_time (not 'moving')."""
    s = sim(max_time=0.01, dt=1e-4)
    r = s.simulate(Schedule.single(10.0, 200e-6), 0.125e-3)  # a 0.1 s stroke
    assert r.outcome == "max_time"
    assert r.end_time_s == pytest.approx(0.01, abs=1e-12)


@pytest.mark.slow
def test_full_episode_study_default_meets_the_bar():
    """The whole study (240 episodes, both modes on the dt ladder): the env default meets the
    bar (p95 <= tolerance/10, outcome and success disagreements <= 0.5 %) and is the cheapest
    setting that does."""
    study = episode_study(progress=False, repeats=1)
    d = study["env_default"]
    assert d is not None and d["p95_error_m"] <= BAR
    assert d["outcome_disagreement_fraction"] <= 0.005
    rec = study["recommended"]
    assert (rec["dt_s"], rec["min_steps"]) == (d["dt_s"], d["min_steps"])
