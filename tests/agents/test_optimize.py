"""Open-loop optimisation (agents/search.py, open_loop.py, dissertation.py, the ``optimize``
command): seeded runs repeat exactly, budgets are never exceeded, the dissertation's cost on
hand-computed cases, the command's JSON and charts."""
import json

import numpy as np
import pytest

pytest.importorskip("cma")

from agents.openloop.dissertation import TABLE_4_3, DissertationProblem, dissertation_cost, \
    evaluate_parameters, solve_dissertation  # noqa: E402
from agents.openloop.target import replay, solve_target  # noqa: E402
from agents.planning import LineRollouts  # noqa: E402
from agents.openloop.search import cmaes_minimize, de_minimize, de_population, minimize  # noqa: E402
from support.cli import run_cli  # noqa: E402


def run(*args):
    """A command in this process (tests/cli start the console script's processes)."""
    return run_cli(*args)


@pytest.mark.parametrize("method", ["de", "cmaes"])
def test_solve_target_is_deterministic_and_within_budget(method):
    roll = LineRollouts()
    a = solve_target(1e-3, method, 60, seed=3, rollouts=roll)
    assert roll.episodes == a.episodes <= 60
    b = solve_target(1e-3, method, 60, seed=3)
    assert np.array_equal(a.plan, b.plan) and a.error_m == b.error_m
    assert a.history_episodes == b.history_episodes
    assert a.plan.shape == (5, 3) and np.all(np.abs(a.plan) <= 1)
    hist = [np.inf if e is None else e for e in a.history_best_abs_error_m]
    assert all(x >= y for x, y in zip(hist, hist[1:], strict=False))  # best so far never worsens
    if a.outcome == "rest":
        assert hist[-1] == a.abs_error_m
    assert a.final_position_m == pytest.approx(1e-3 + a.error_m, abs=1e-15)
    assert len(a.firings["frequency_hz"]) == 5 and 200 <= min(a.firings["frequency_hz"])
    c = solve_target(1e-3, method, 60, seed=4)
    assert not np.array_equal(a.plan, c.plan)


def test_best_plan_replays_to_the_same_end():
    res = solve_target(1.5e-3, "de", 45, seed=0)
    r = replay(res.plan, 1.5e-3, copies=3)
    assert np.all(r.error_m == res.error_m) and np.all(r.outcome == res.outcome)
    assert r.success.tolist() == [res.success] * 3


@pytest.mark.parametrize("budget", [10, 37, 100, 333])
def test_budget_rule_exact(budget):
    sizes = []

    def sphere(X):
        sizes.append(X.shape[0])
        return ((X - 0.2) ** 2).sum(1)

    box = [(-1.0, 1.0)] * 6
    for method in ("de", "cmaes"):
        sizes.clear()
        res = minimize(method, sphere, box, budget, seed=1)
        assert res.episodes == sum(sizes) <= budget
        assert res.history_episodes[-1] == res.episodes and len(sizes) == res.generations
        if method == "de":  # every full generation is used
            pop = de_population(budget, 6)
            assert res.episodes == pop * (budget // pop) and set(sizes) == {pop}
        else:  # no generation left unstarted that would have fitted
            assert budget - res.episodes < 2 * max(sizes)


def test_search_arguments_checked():
    f = lambda X: X.sum(1)  # noqa: E731
    with pytest.raises(ValueError, match="method"):
        minimize("nelder", f, [(0, 1)], 100, 0)
    with pytest.raises(ValueError, match="budget"):
        de_minimize(f, [(0, 1)] * 3, 20, 0, popsize=50)
    with pytest.raises(ValueError, match="bounds"):
        cmaes_minimize(f, [(1, 0)], 100, 0)


def test_cmaes_leaves_global_random_state_alone():
    state = np.random.get_state()[1].copy()
    cmaes_minimize(lambda X: (X ** 2).sum(1), [(-1, 1)] * 3, 40, seed=0)
    assert np.array_equal(np.random.get_state()[1], state)


def test_dissertation_cost_hand_computed():
    p = DissertationProblem()  # A = 1e3 1/s, T_d = 50 um, C = 10, P = 1e5, target 10 mm
    assert (p.time_weight, p.scale_m, p.exponent, p.penalty, p.target_m) == \
        (1e3, 50e-6, 10.0, 1e5, 10e-3)
    # reached: 20 um off after 37 ms -> 37 + 0.4^10
    c = dissertation_cost(10.02e-3, 0.037, True, p)
    assert c == pytest.approx(37.0 + 0.4 ** 10, rel=1e-12)
    # missed by 100 um after 50 ms -> 50 + 2^10
    assert dissertation_cost(9.9e-3, 0.05, True, p) == pytest.approx(50.0 + 1024.0, rel=1e-12)
    # detached: the penalty on top of not moving from x0 = -0.15 mm (10.15 mm = 203 T_d)
    det = dissertation_cost(5e-3, 0.004, False, p)
    assert det == pytest.approx(1e5 + 203.0 ** 10, rel=1e-12)
    # any rest nearer the target than the start costs less than a detachment
    x = np.linspace(-0.14e-3, 20.1e-3, 50)
    assert np.all(dissertation_cost(x, p.config.max_time, np.ones(50, bool), p) < det)
    # vectorised, mixed outcomes
    v = dissertation_cost([10.02e-3, 5e-3], [0.037, 0.004], [True, False], p)
    assert v[0] == pytest.approx(c) and v[1] == det


def test_table_4_3_schedule_in_this_model():
    """On chapter 4's surface (the problem's default) the schedule carries the part 0.66 mm, on
    chapter 3's (v0's) 0.067 mm: the figures issue 19 measured independently."""
    from microconveyor_env.presets import load_preset

    r = evaluate_parameters(TABLE_4_3)
    assert r["outcome"] == "rest" and r["final_position_m"] == pytest.approx(0.659e-3, abs=1e-6)
    ch3 = DissertationProblem(contact=load_preset("feasibility").contact)
    r3 = evaluate_parameters(TABLE_4_3, ch3)
    assert r3["outcome"] == "rest" and r3["final_position_m"] == pytest.approx(0.067e-3, abs=1e-6)


def test_dissertation_small_run_deterministic():
    a = solve_dissertation("de", seed=2, budget=60, popsize=10)
    b = solve_dissertation("de", seed=2, budget=60, popsize=10)
    assert a.parameters == b.parameters and a.episodes == 60 and a.generations == 6
    lo = {"frequency_hz": 200, "spacing_m": 500e-6, "delay_s": 0, "stroke_m": 100e-6}
    hi = {"frequency_hz": 1e4, "spacing_m": 1500e-6, "delay_s": 0.1, "stroke_m": 200e-6}
    assert all(lo[k] <= v <= hi[k] for k, v in a.parameters.items())
    assert a.cost == pytest.approx(evaluate_parameters(a.parameters)["cost"], rel=1e-12)
    c = solve_dissertation("cmaes", seed=2, budget=40)
    d = solve_dissertation("cmaes", seed=2, budget=40)
    assert c.parameters == d.parameters and c.episodes <= 40


def test_optimize_cli_json_and_charts(tmp_path):
    r = run("optimize", "--problem", "dissertation", "--budget", "20", "--popsize", "5",
            "--json", "--plot", str(tmp_path / "d" / "plan.png"))
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["episodes"] == 20 and len(out["history_best_cost"]) == 4
    assert out["table_4_3"]["dissertation"]["frequency_hz"] == 719.0
    assert set(out["parameters"]) == {"frequency_hz", "spacing_m", "delay_s", "stroke_m"}
    for name in ("plan_history.png", "plan.png"):  # one --plot FILE, companions beside it
        assert (tmp_path / "d" / name).read_bytes()[:4] == b"\x89PNG"
    r = run("optimize", "--problem", "target", "--target", "2e-3", "--budget", "30",
            "--method", "cmaes", "--seed", "0", "--json", "--plot", str(tmp_path / "t" / "p"))
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["episodes"] <= 30 and len(out["plan"]) == 5 and out["method"] == "cmaes"
    assert (tmp_path / "t" / "p_history.png").read_bytes()[:4] == b"\x89PNG"
    assert (tmp_path / "t" / "p.png").read_bytes()[:4] == b"\x89PNG"
    r = run("optimize", "--budget", "30", "--plot", str(tmp_path), "--json")
    assert r.returncode == 2 and "is a folder; give a file name" in json.loads(r.stdout)["error"]
    r = run("optimize", "--budget", "5", "--json")
    assert r.returncode == 2 and "budget" in json.loads(r.stdout)["error"]


@pytest.mark.slow
def test_dissertation_de_full_run():
    """The dissertation's DE (50 x 50, CR 0.8, F 0.9): 2,550 episodes, repeatable."""
    a = solve_dissertation("de", seed=0)
    assert a.episodes == 2550 and a.generations == 51 and a.outcome == "rest"
    assert a.final_position_m > 1e-3  # far beyond Table 4.3's 0.067 mm in this model
    b = solve_dissertation("de", seed=0)
    assert a.parameters == b.parameters and a.history_best_cost == b.history_best_cost


def test_randomised_env_plays_one_episode_per_search():
    """With per-episode randomisation on, every candidate plays the episode of `episode_seed`;
    replaying the best plan with that seed gives the same end, other seeds other episodes."""
    import dataclasses

    from microconveyor_env.envs import EnvConfig

    cfg = dataclasses.replace(EnvConfig.from_yaml(), action_noise=0.01,
                              friction_factor_range=(0.8, 1.2), mass_factor_range=(0.8, 1.2))
    a = solve_target(1e-3, "de", 30, seed=0, config=cfg, episode_seed=7)
    assert replay(a.plan, 1e-3, cfg, seed=7).error_m[0] == a.error_m
    r = replay(a.plan, 1e-3, cfg, copies=4, seed=7)
    assert r.error_m[0] == a.error_m and len(set(r.error_m.tolist())) == 4


def test_explain_rows_summarise_their_seeds():
    from agents.openloop.table43 import GOAL, VARIANTS, explain

    rows = explain(seeds=[0, 1, 2], budget=100, variants=VARIANTS[:2])
    shipped, ch3 = rows
    assert shipped["variant"].startswith("as shipped") and "feasibility" in ch3["variant"]
    assert shipped["table43_final_position_m"] == pytest.approx(0.659e-3, abs=1e-6)
    assert ch3["table43_final_position_m"] == pytest.approx(0.067e-3, abs=1e-6)
    for r in rows:
        x, t = np.array(r["de_final_position_m"]), np.array(r["de_travel_time_s"])
        assert r["de_seeds"] == [0, 1, 2] and len(x) == len(t) == 3
        assert r["de_median_final_position_m"] == np.median(x)
        hits = (np.abs(x - 10e-3) <= GOAL["tolerance_m"]) & (t <= GOAL["travel_time_s"])
        assert r["de_goal_hits"] == int(hits.sum())
        assert r["de_median_seed"]["final_position_m"] == np.median(x)  # odd count: a member
    # the same seed and budget give the same optimum as a direct run
    direct = solve_dissertation("de", seed=1, budget=100)
    assert shipped["de_final_position_m"][1] == direct.final_position_m


@pytest.mark.slow
def test_ten_seed_dissertation_de_on_its_own_surface():
    """The dissertation's DE (50 x 50, CR 0.8, F 0.9) on chapter 4's surface, seeds 0-9
    (docs/agents.md §1): every run rests; the median seed stops at 6.91 mm, twice what
    chapter 3's surface allowed (3.5 mm) and short of the dissertation's 10.02 mm. The kernel
    and the table are bit-identical across machines (docs/physics.md §2.3), so DE's path is too:
    1 µm on the median guards that, not a numerical tolerance."""
    runs = [solve_dissertation("de", seed=s) for s in range(10)]
    x = np.array([r.final_position_m for r in runs])
    assert all(r.outcome == "rest" and r.episodes == 2550 for r in runs)
    assert np.median(x) == pytest.approx(6.912e-3, abs=1e-6)
    assert 6.2e-3 < x.min() and x.max() < 8.0e-3
    assert not np.any(np.abs(x - 10e-3) <= 50e-6)  # the stated budget reaches 10 mm for no seed


def test_default_budget_reaches_8mm_on_v1():
    """At its default budget DE plans MicroConveyor-v1's 8 mm target to rest within the
    tolerance (at 2000 episodes its population collapsed on a plan resting ~0.5 mm short)."""
    from agents.openloop.search import TARGET_BUDGET

    r = run("optimize", "--target", "8e-3", "--env", "MicroConveyor-v1", "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["budget"] == TARGET_BUDGET and out["episodes"] <= TARGET_BUDGET
    assert out["outcome"] == "rest" and out["success"] and out["abs_error_m"] <= 50e-6
