"""The plane's firing map from rest (microconveyor_env/physics/plane/firing_map.py): a radial
bump moves a resting part along the line through the actuator, by an amount that depends on the
radial offset, frequency and stroke alone; the map tabulates that on the full plane model, its
held-out error stays within the bound it is quoted with, nothing it trusts detaches, and it is
cached whole."""
import math

import numpy as np
import pytest

from microconveyor_env.envs.core.versions import scene_config
from microconveyor_env.envs.plane.firing_map import firing_map, reach_m, rest_grid
from microconveyor_env.envs.plane.state import make_plane_simulator
from microconveyor_env.physics import dynamics_kernel as k1
from microconveyor_env.physics.firing_map import MapGrid
from microconveyor_env.physics.materials import ParameterError
from microconveyor_env.physics.plane import firing_map as pfm
from microconveyor_env.physics.plane.firing_map import (PlaneFiringMap, full_firings,
                                                        full_strokes)

ENV = "MicroConveyor2D-v1"
# The bound the plane's map is quoted with: on 20,000 held-out firings from rest in every
# direction its largest error was 1.4 µm (99th percentile 0.64 µm, 0.42 % of the distance
# travelled at most); the bound leaves room for another sample.
BOUND_MAX_M = 3e-6
BOUND_P99_M = 1.5e-6
BOUND_RELATIVE = 0.01
ROUNDING_M = 1e-15   # [m] what rounding leaves of a displacement off the radial line


@pytest.fixture(scope="module")
def plane_map():
    return firing_map(scene_config(ENV))


def test_the_plane_map_keeps_its_error_bound_on_held_out_firings(plane_map):
    e = plane_map.verify(n=2000, seed=2026)
    assert e.to_rest and e.samples == 2000
    assert e.misclassified_detachments == 0          # nothing trusted detaches on the full model
    assert e.error_max_m <= BOUND_MAX_M and e.error_p99_m <= BOUND_P99_M
    assert e.relative_error_max <= BOUND_RELATIVE
    assert 0.7 <= e.trusted_share <= 0.9             # the rest: detachment and its edge
    assert e.untrusted_on_surface_share <= 0.03
    # the full model itself: radial, and the same in every direction (to rounding)
    assert e.perpendicular_max_m <= ROUNDING_M and e.rotation_max_m <= ROUNDING_M
    assert e.map_query_s > 0 and e.full_stroke_s > 0


def test_a_firing_from_rest_moves_the_part_along_the_line_through_the_actuator():
    sim = make_plane_simulator(scene_config(ENV))
    rng = np.random.default_rng(7)
    n = 60
    r = rng.uniform(50e-6, 700e-6, n)
    theta = rng.uniform(0.0, 2 * math.pi, n)
    f = np.exp(rng.uniform(math.log(200.0), math.log(900.0), n))
    h = rng.uniform(100e-6, 200e-6, n)
    act = rng.uniform(0.0, 2e-3, (n, 2))
    e = np.stack([np.cos(theta), np.sin(theta)], 1)
    end, _, code = full_firings(sim, act + r[:, None] * e, act, f, h)
    axis, _, code_axis = full_firings(sim, np.stack([r, np.zeros(n)], 1), np.zeros((n, 2)), f, h)
    assert np.array_equal(code, code_axis)
    rest = code == k1.REST
    assert rest.sum() >= 30
    moved = end[rest] - act[rest] - r[rest, None] * e[rest]
    along = moved[:, 0] * e[rest, 0] + moved[:, 1] * e[rest, 1]
    perp = moved[:, 1] * e[rest, 0] - moved[:, 0] * e[rest, 1]
    assert np.abs(along).max() > 50e-6                                # it did move
    assert np.abs(perp).max() <= 4 * ROUNDING_M                       # along the line
    assert np.allclose(along, axis[rest, 0] - r[rest], rtol=0, atol=4 * ROUNDING_M)


def test_the_map_returns_the_full_model_at_its_nodes(plane_map):
    m = plane_map
    r, _, f, h = m.grid.nodes()
    rng = np.random.default_rng(0)
    i, j, k = rng.integers(0, len(r), 60), rng.integers(0, len(f), 60), rng.integers(0, len(h), 60)
    dr, vr, ok = m.stroke(r[i], 0.0, f[j], h[k])
    ref_dr, ref_vr, perp, code = full_strokes(m.plane, r[i], f[j], h[k])
    on = code == k1.MOVING
    assert np.array_equal(m.ok[i, 0, j, k], on) and not np.any(ok & ~on)
    assert np.all(perp == 0.0)
    both = ok & on
    assert both.sum() >= 30
    assert np.allclose(dr[both], ref_dr[both], rtol=0, atol=1e-15)
    assert np.allclose(vr[both], ref_vr[both], rtol=0, atol=1e-12)


def test_a_trusted_rest_in_the_plane_is_the_full_model_s(plane_map):
    m = plane_map
    rng = np.random.default_rng(3)
    n = 400
    act = rng.uniform(0.0, 2e-3, (n, 2))
    part = act + rng.uniform(-0.8e-3, 0.8e-3, (n, 2))
    f = np.exp(rng.uniform(math.log(200.0), math.log(2000.0), n))
    h = rng.uniform(100e-6, 200e-6, n)
    pred, t, ok = m.rest_at(part, act, f, h)
    true, t_true, code = full_firings(m.plane, part, act, f, h)
    assert ok.sum() > 200 and np.all(code[ok] == k1.REST)           # trusted: never detaches
    err = np.hypot(*(pred[ok] - true[ok]).T)
    assert err.max() <= BOUND_MAX_M
    assert np.allclose(t[ok], t_true[ok], rtol=0.05, atol=2e-4)     # when it rests
    assert np.isnan(pred[~ok]).all()


def test_the_rest_grid_spans_every_actuator_an_aim_picks():
    cfg = scene_config(ENV)
    g = rest_grid(cfg)
    assert g.offset_m[0] == 0.0 and g.offset_m[1] >= reach_m(cfg)
    assert reach_m(cfg) == pytest.approx(math.sqrt(2) * 0.75e-3)
    assert g.velocity_m_s == (0.0, 0.0, 1)
    assert g.frequency_hz[:2] == tuple(cfg.freq_range) and g.stroke_m[:2] == tuple(cfg.stroke_range)


def test_a_grid_that_is_not_radial_from_rest_is_refused():
    sim = make_plane_simulator(scene_config(ENV))
    for g in (MapGrid((-1e-4, 1e-4, 3), (0.0, 0.0, 1), (300.0, 900.0, 3), (1e-4, 2e-4, 2)),
              MapGrid((0.0, 1e-4, 3), (0.0, 0.1, 3), (300.0, 900.0, 3), (1e-4, 2e-4, 2))):
        with pytest.raises(ParameterError, match="from rest"):
            PlaneFiringMap.build(sim, g)


def test_the_plane_map_is_cached_and_a_damaged_file_is_rebuilt(tmp_path, monkeypatch):
    monkeypatch.setenv("MICROCONVEYOR_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(pfm, "_MEMO", {})
    sim = make_plane_simulator(scene_config(ENV))
    g = MapGrid((0.0, 0.4e-3, 5), (0.0, 0.0, 1), (300.0, 900.0, 3), (100e-6, 200e-6, 2))
    a = PlaneFiringMap.cached(sim, g)
    assert PlaneFiringMap.cached(sim, g) is a
    files = list(tmp_path.glob("plane-firing-map-*.npz"))
    assert len(files) == 1
    monkeypatch.setattr(pfm, "_MEMO", {})
    b = PlaneFiringMap.cached(sim, g)
    assert b is not a and np.array_equal(b.dx, a.dx) and np.array_equal(b.ok, a.ok)
    files[0].write_bytes(b"not a map")
    monkeypatch.setattr(pfm, "_MEMO", {})
    c = PlaneFiringMap.cached(sim, g)
    assert np.array_equal(c.dx, a.dx)
    with np.load(files[0]) as z:
        assert np.array_equal(z["dx"], a.dx)


def test_the_firing_map_command_reports_the_plane(plane_map):
    """``microconveyor firing-map --env MicroConveyor2D-v1``: the plane's row, from rest, within
    the bound, in JSON (SI) and for people (µm, µs)."""
    import json

    from microconveyor_env.studies.fidelity import MAP_ENV_IDS

    from support.cli import run_cli

    assert ENV in MAP_ENV_IDS
    r = run_cli("firing-map", "--env", ENV, "--samples", "300", "--json")
    assert r.returncode == 0, r.stderr
    row, = json.loads(r.stdout)["maps"]
    assert row["env_id"] == ENV and row["from_rest"] and row["at_rest"] is None
    assert row["misclassified_detachments"] == 0 and row["error_max_m"] <= BOUND_MAX_M
    human = run_cli("firing-map", "--env", ENV, "--samples", "300")
    assert f"{ENV} (firings from rest)" in human.stdout and "µs per query" in human.stdout
