"""The firing map (microconveyor_env/physics/firing_map.py): a stroke's outcome tabulated on a
grid and interpolated. Its nodes are the full model's strokes; between them its error on
held-out strokes stays within the bound it is quoted with; nothing it trusts detaches; it is
cached whole and rebuilt from a damaged file."""
import json
import math

import numpy as np
import pytest

from microconveyor_env.envs.core.versions import scene_config
from microconveyor_env.envs.rail.firing_map import firing_map, rest_grid
from microconveyor_env.envs.rail.parts import make_simulator
from microconveyor_env.physics import firing_map as fm
from microconveyor_env.physics.firing_map import FiringMap, MapGrid, full_strokes
from microconveyor_env.physics.materials import ParameterError
from support.cli import run_cli

# The bound the positioner's map is quoted with (docs/results.md, "Firing maps"): measured on
# 20,000 held-out firings from rest its largest error was 7.0 µm (99th percentile 2.7 µm, 0.67 %
# of the displacement at most); the bound leaves room for another seed's sample.
BOUND_MAX_M = 10e-6
BOUND_P99_M = 4e-6
BOUND_RELATIVE = 0.01


@pytest.fixture(scope="module")
def positioner_map():
    return firing_map(scene_config("MicroPositioner-v0"))


def test_the_positioner_map_keeps_its_error_bound_on_held_out_firings(positioner_map):
    e = positioner_map.verify(n=3000, seed=2026)
    assert e.to_rest and e.samples == 3000
    assert e.misclassified_detachments == 0         # nothing trusted detaches on the full model
    assert e.error_max_m <= BOUND_MAX_M and e.error_p99_m <= BOUND_P99_M
    assert e.relative_error_max <= BOUND_RELATIVE
    assert 0.7 <= e.trusted_share <= 0.9            # the rest: detachment and its edge
    assert e.untrusted_on_surface_share <= 0.03     # the edge band the planner leaves out
    assert e.map_query_s > 0 and e.full_stroke_s > 0   # timed (compared in the benchmark)


def test_the_map_returns_the_full_model_at_its_nodes(positioner_map):
    m = positioner_map
    u, _, f, h = m.grid.nodes()
    rng = np.random.default_rng(0)
    iu, jf, kh = rng.integers(0, len(u), 40), rng.integers(0, len(f), 40), rng.integers(0, len(h), 40)
    dx, v, ok = m.stroke(u[iu], 0.0, f[jf], h[kh])
    ref_dx, ref_v, code = full_strokes(m.sim, u[iu], np.zeros(40), f[jf], h[kh])
    on = code == 3   # the stroke ran to its end on the surface (MOVING)
    # trusted needs every corner of the cell on the surface, so a trusted node is one
    assert not np.any(ok & ~m.ok[iu, 0, jf, kh]) and np.array_equal(m.ok[iu, 0, jf, kh], on)
    # a trusted node is its stroke, to rounding of the weights (exactly 0 and 1 at a node)
    both = ok & on
    assert both.sum() >= 20
    assert np.allclose(dx[both], ref_dx[both], rtol=0, atol=1e-15)
    assert np.allclose(v[both], ref_v[both], rtol=0, atol=1e-12)


def test_outside_the_grid_nothing_is_trusted(positioner_map):
    m = positioner_map
    g = m.grid
    dx, t, ok = m.rest([g.offset_m[1] + 1e-6, 0.0, 0.0, 0.0],
                       [500.0, g.frequency_hz[1] * 1.01, 500.0, math.nan], [150e-6] * 4)
    assert list(ok) == [False, False, True, False]
    assert np.isnan(dx[[0, 1, 3]]).all() and np.isfinite(dx[2])


def test_a_part_far_from_the_bump_stays_where_it_rests():
    # a resting part 0.35 mm from a Gaussian bump of width 0.1 mm: the slope under it is far
    # below what breaks its static friction, so the stroke moves it by nothing at all
    sim = make_simulator(scene_config("MicroPositioner-v0"))
    g = MapGrid((0.34e-3, 0.36e-3, 3), (0.0, 0.0, 1), (300.0, 600.0, 3), (100e-6, 200e-6, 2))
    m = FiringMap.build(sim, g)
    assert m.ok.all() and np.all(m.dx == 0.0) and np.all(m.v_end == 0.0)
    dx, t, ok = m.rest(0.35e-3, 400.0, 150e-6)
    assert ok[0] and dx[0] == 0.0 and t[0] == pytest.approx(1 / 400.0)   # the stroke's time


def test_the_map_is_cached_and_a_damaged_file_is_rebuilt(tmp_path, monkeypatch):
    monkeypatch.setenv("MICROCONVEYOR_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(fm, "_MEMO", {})
    sim = make_simulator(scene_config("MicroPositioner-v0"))
    g = MapGrid((-0.1e-3, 0.1e-3, 5), (0.0, 0.0, 1), (300.0, 900.0, 3), (100e-6, 200e-6, 2))
    a = FiringMap.cached(sim, g)
    assert FiringMap.cached(sim, g) is a
    files = list(tmp_path.glob("firing-map-*.npz"))
    assert len(files) == 1
    monkeypatch.setattr(fm, "_MEMO", {})
    b = FiringMap.cached(sim, g)                   # read back from the file
    assert b is not a and np.array_equal(b.dx, a.dx) and np.array_equal(b.ok, a.ok)
    files[0].write_bytes(b"not a map")
    monkeypatch.setattr(fm, "_MEMO", {})
    c = FiringMap.cached(sim, g)                   # rebuilt, and the file rewritten whole
    assert np.array_equal(c.dx, a.dx)
    with np.load(files[0]) as z:
        assert np.array_equal(z["dx"], a.dx)


@pytest.mark.parametrize("grid", [
    ((0.0, 1e-3, 1), (0.0, 0.0, 1), (200.0, 2000.0, 3), (1e-4, 2e-4, 2)),   # one node, lo != hi
    ((0.0, 1e-3, 3), (0.0, 0.0, 1), (0.0, 2000.0, 3), (1e-4, 2e-4, 2)),     # 0 Hz
    ((1e-3, 0.0, 3), (0.0, 0.0, 1), (200.0, 2000.0, 3), (1e-4, 2e-4, 2)),   # hi < lo
    ((0.0, 1e-3, 2.5), (0.0, 0.0, 1), (200.0, 2000.0, 3), (1e-4, 2e-4, 2)), # nodes not an int
])
def test_a_bad_grid_is_refused(grid):
    with pytest.raises(ParameterError, match="MapGrid"):
        MapGrid(*grid)


def test_the_rest_grid_spans_the_candidates_a_planner_aims_at():
    cfg = scene_config("MicroPositioner-v0")
    g = rest_grid(cfg)
    assert g.offset_m[1] >= 1.5 * cfg.spacing and g.offset_m[0] == -g.offset_m[1]
    assert g.frequency_hz[:2] == tuple(cfg.freq_range) and g.stroke_m[:2] == tuple(cfg.stroke_range)
    assert (g.offset_m[1] - g.offset_m[0]) / (g.offset_m[2] - 1) == pytest.approx(2.5e-6)


def test_the_firing_map_command_reports_error_and_speed(positioner_map):
    r = run_cli("firing-map", "--env", "MicroPositioner-v0", "--samples", "400", "--json")
    assert r.returncode == 0, r.stderr
    row, = json.loads(r.stdout)["maps"]
    assert row["env_id"] == "MicroPositioner-v0" and row["from_rest"] and row["at_rest"] is None
    assert row["samples"] == 400 and row["misclassified_detachments"] == 0
    assert row["error_max_m"] <= BOUND_MAX_M and row["speedup"] > 1
    human = run_cli("firing-map", "--env", "MicroPositioner-v0", "--samples", "400")
    assert "MicroPositioner-v0 (firings from rest)" in human.stdout and "µs per query" in human.stdout
    bad = run_cli("firing-map", "--env", "MicroConveyor2D-v9")
    assert bad.returncode != 0 and "invalid choice: 'MicroConveyor2D-v9'" in bad.stderr
