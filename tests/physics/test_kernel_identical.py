"""The compiled kernels give the same bits as the stored outputs (tests/data/kernel_outputs.json).

A fixed set of firings on several scenes -- MicroConveyor-v1's (event mode) and its Karnopp
variant, v0's surface with exact kinematics, the other two shapes, a tilted carrier with a
randomised part (mass and friction factors), stretch-dependent roughness -- from rest and
moving, one stroke or run to rest (as the positioner fires), a frequency ladder across
detachment, whole five-actuator schedules with delays (the stored v0 episodes), and recorded
trajectories; and the plane's kernel on its test scenes. Every output slot of
:func:`~microconveyor_env.physics.dynamics_kernel.run` (end state, time, outcome, event time and
place, step and event counts) and every recorded row must equal the stored value exactly (``==``):
a change that keeps each float operation's inputs and order keeps them; one that reorders a sum
or fuses a multiply-add does not.

The file stores inputs and outputs (floats as ``float.hex``); it was written by

    python tests/physics/test_kernel_identical.py --write

which is to be run again only when the dynamics change on purpose (then the stored env rollouts
and the shipped policies' evaluations move too).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from microconveyor_env.physics import dynamics_kernel as k1
from microconveyor_env.physics import forces
from microconveyor_env.physics.plane import kernel as k2
from microconveyor_env.physics.plane.simulator import PlaneSimulator
from microconveyor_env.presets import load_preset, simulator

DATA = Path(__file__).resolve().parent.parent / "data"
FILE = DATA / "kernel_outputs.json"
LINE = {"dt": 1e-4, "min_steps": 48, "max_time": 1.0}  # MicroConveyor-v0/-v1's integration
# scene name -> (preset, Simulator keywords, factors on P[I_MASS] and P[I_FSCALE])
SCENES: dict[str, tuple[str, dict[str, Any], tuple[float, float]]] = {
    "v1_event": ("conveyor", {**LINE, "mode": "event"}, (1.0, 1.0)),
    "v1_karnopp": ("conveyor", {**LINE, "mode": "karnopp"}, (1.0, 1.0)),
    "v0_exact_event": ("feasibility", {**LINE, "mode": "event", "kinematics": "exact"},
                       (1.0, 1.0)),
    "v0_exact_karnopp": ("feasibility", {**LINE, "mode": "karnopp", "kinematics": "exact"},
                         (1.0, 1.0)),
    "sinusoidal": ("conveyor", {**LINE, "mode": "event", "shape": "sinusoidal"}, (1.0, 1.0)),
    "clamped_beam": ("conveyor", {**LINE, "mode": "event", "shape": "clamped_beam"}, (1.0, 1.0)),
    "tilted_randomised": ("conveyor", {**LINE, "mode": "event", "slope": 0.02}, (1.04, 0.97)),
    "stretch_event": ("feasibility", {**LINE, "mode": "event", "roughness": "stretch",
                                      "n_sigma": 3}, (1.0, 1.0)),
    "stretch_karnopp": ("feasibility", {**LINE, "mode": "karnopp", "roughness": "stretch",
                                        "n_sigma": 3}, (1.0, 1.0)),
}
RECORDED = ("v1_event", "v1_karnopp", "v0_exact_event", "stretch_event")  # rows stored
EPISODE_ACTUATORS = [0.5e-3 * i for i in range(5)]
PLANE_GRID = ((0.0, 0.0), (0.5e-3, 0.0), (0.25e-3, 0.4e-3))
# (firings (actuator, f [Hz], h [m], delay [s]), start (x, y, vx, vy)): a pass-by, a relay of
# three actuators from rest, a slow oblique stop (the plane tests' scenes)
PLANE_RUNS = (
    (((0, 700.0, 200e-6, 0.0),), (0.12e-3, 0.05e-3, 0.0, 0.03)),
    (((0, 950.0, 200e-6, 0.0), (2, 800.0, 180e-6, 1e-3), (1, 600.0, 150e-6, 0.0)),
     (0.1e-3, -0.06e-3, 0.0, 0.0)),
    (((2, 500.0, 200e-6, 0.0),), (0.3e-3, 0.2e-3, -0.02, 0.01)),
    (((0, 1400.0, 200e-6, 0.0),), (-0.15e-3, 0.02e-3, 0.0, 0.0)),
)


def _hex(a: Any) -> Any:
    if isinstance(a, (list, tuple, np.ndarray)):
        return [_hex(x) for x in a]
    return float(a).hex()


def _unhex(a: Any) -> Any:
    if isinstance(a, list):
        return [_unhex(x) for x in a]
    return float.fromhex(a)


def line_runs() -> list[dict[str, Any]]:
    """The 1-D runs' inputs (actuator at 0 unless a schedule): plain floats."""
    rng = np.random.default_rng(20240617)
    runs: list[dict[str, Any]] = []
    for i in range(20):  # the env's spread, frequencies up to 2.5 kHz (detachments)
        runs.append({"xa": [0.0], "f": [float(np.exp(rng.uniform(np.log(200.0), np.log(2.5e3))))],
                     "h": [float(rng.uniform(100e-6, 200e-6))], "delay": [0.0],
                     "x0": float(rng.uniform(-0.3e-3, 0.3e-3)),
                     "v0": float(rng.uniform(-0.4, 0.4)) if i % 2 else 0.0,
                     "to_rest": False, "record": False})
    for x0, f, h in ((-0.125e-3, 950.0, 200e-6), (0.2e-3, 400.0, 150e-6),
                     (-0.05e-3, 1200.0, 120e-6), (0.1e-3, 700.0, 180e-6)):  # to rest from rest
        runs.append({"xa": [0.0], "f": [f], "h": [h], "delay": [0.0], "x0": x0, "v0": 0.0,
                     "to_rest": True, "record": False})
    for f in range(700, 1500, 100):  # across detachment
        for h, x0 in ((200e-6, -0.15e-3), (120e-6, 0.1e-3)):
            runs.append({"xa": [0.0], "f": [float(f)], "h": [h], "delay": [0.0], "x0": x0,
                         "v0": 0.0, "to_rest": False, "record": False})
    for x0, v0 in ((-0.2e-3, 0.35), (0.05e-3, -0.25), (-0.25e-3, 0.1)):  # engaging a moving part
        runs.append({"xa": [0.0], "f": [500.0], "h": [150e-6], "delay": [2e-3], "x0": x0,
                     "v0": v0, "to_rest": True, "record": False})
    episodes = json.loads((DATA / "episodes.json").read_text())["episodes"]
    for e in episodes[::2]:  # five-actuator schedules with delays, to rest
        runs.append({"xa": EPISODE_ACTUATORS, "f": e["frequency_hz"], "h": e["stroke_m"],
                     "delay": e["delay_s"], "x0": -0.15e-3, "v0": 0.0, "to_rest": True,
                     "record": False})
    runs.append({"xa": [0.0], "f": [950.0], "h": [200e-6], "delay": [0.0], "x0": 0.125e-3,
                 "v0": 0.0, "to_rest": True, "record": True})
    runs.append({"xa": [0.0], "f": [600.0], "h": [180e-6], "delay": [1e-3], "x0": -0.2e-3,
                 "v0": 0.3, "to_rest": False, "record": True})
    return runs


def line_simulator(name: str):
    preset, kw, (mass, friction) = SCENES[name]
    sim = simulator(preset, **kw)
    P = sim.params.copy()
    P[forces.I_MASS] *= mass
    P[forces.I_FSCALE] *= friction
    return sim, P


def run_line(sim, P: np.ndarray, r: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """(out, recorded rows) of one run through the compiled 1-D kernel."""
    arr = [np.asarray(r[k], dtype=float) for k in ("xa", "f", "h", "delay")]
    rec = np.zeros((4096 if r["record"] else 0, k1.N_REC))
    out = np.zeros(k1.N_OUT)
    k1.run(*arr, r["x0"], r["v0"], 0.0, sim.dt, sim.min_steps, r["to_rest"],  # type: ignore[call-arg]
           sim.max_time, P, *sim.tables, rec, out)
    return out, rec[:int(out[k1.O_NREC])]


def plane_simulator() -> PlaneSimulator:
    return PlaneSimulator(load_preset("feasibility").contact, dt=1e-4, min_steps=48,
                          max_time=1.0)


def run_plane(sim: PlaneSimulator, firings, start) -> np.ndarray:
    xa = np.array([PLANE_GRID[a][0] for a, *_ in firings])
    ya = np.array([PLANE_GRID[a][1] for a, *_ in firings])
    f, h, d = (np.array([fi[k] for fi in firings]) for k in (1, 2, 3))
    out = np.zeros(k2.N_OUT)
    k2.run(xa, ya, f, h, d, *start, 0.0, sim.dt, sim.min_steps, True,  # type: ignore[call-arg]
           sim.max_time, sim.params, *sim.tables, np.zeros((0, k2.N_REC)), out)
    return out


def compute() -> dict[str, Any]:
    """Every scene's runs with today's kernels, floats as hex."""
    runs = line_runs()
    data: dict[str, Any] = {
        "about": __doc__.split("\n\n")[0],
        "runs": [{k: v if isinstance(v, bool) else _hex(v) for k, v in r.items()} for r in runs],
        "scenes": {}, "plane": []}
    for name in SCENES:
        sim, P = line_simulator(name)
        rows = []
        for r in runs:
            out, rec = run_line(sim, P, r)
            rows.append({"out": _hex(out), **({"rec": _hex(rec)} if r["record"]
                                              and name in RECORDED else {})})
        data["scenes"][name] = rows
    psim = plane_simulator()
    for firings, start in PLANE_RUNS:
        data["plane"].append({"out": _hex(run_plane(psim, firings, start))})
    return data


@pytest.fixture(scope="module")
def stored() -> dict[str, Any]:
    return json.loads(FILE.read_text())


FAST = {"v1_event"}   # the envs' path; the others each compile a kernel of their own (slow tier)


@pytest.mark.parametrize("name", [n if n in FAST else pytest.param(n, marks=pytest.mark.slow)
                                  for n in sorted(SCENES)])
def test_line_kernel_gives_the_stored_bits(stored, name):
    sim, P = line_simulator(name)
    runs = [{k: v if isinstance(v, bool) else _unhex(v) for k, v in r.items()}
            for r in stored["runs"]]
    for i, (r, row) in enumerate(zip(runs, stored["scenes"][name], strict=True)):
        out, rec = run_line(sim, P, r)
        want = np.array(_unhex(row["out"]))
        assert np.array_equal(out, want, equal_nan=True), (name, i, out - want)
        if "rec" in row:
            want_rec = np.array(_unhex(row["rec"]))
            assert rec.shape == want_rec.shape and np.array_equal(rec, want_rec), (name, i)


def test_the_stored_runs_cover_the_kernels_paths(stored):
    """Detachments, runs to rest, located events and both stick and slip are in the set."""
    outs = np.array([_unhex(r["out"]) for rows in stored["scenes"].values() for r in rows])
    codes = set(outs[:, k1.O_OUTCOME].astype(int).tolist())
    assert {k1.REST, k1.DETACHED, k1.MOVING} <= codes
    assert (outs[:, k1.O_EVENTS] > 0).sum() > 50


def test_plane_kernel_gives_the_stored_bits(stored):
    sim = plane_simulator()
    for (firings, start), row in zip(PLANE_RUNS, stored["plane"], strict=True):
        out = run_plane(sim, firings, start)
        want = np.array(_unhex(row["out"]))
        assert np.array_equal(out, want, equal_nan=True), (firings, out - want)


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        sys.exit(__doc__)
    FILE.write_text(json.dumps(compute(), separators=(",", ":")) + "\n", encoding="utf-8")
    print(f"wrote {FILE} ({FILE.stat().st_size} bytes)")
