"""Shared hypothesis strategies: physical values, edge values and wrongly typed junk."""
import math

from hypothesis import strategies as st

EDGE_FLOATS = (0.0, -0.0, -1.0, 5e-324, 1e-300, 1e300, 1.7e308, math.nan, math.inf, -math.inf)
JUNK = (True, False, None, "1e-3", "abc", [1.0], {}, (1.0, 2.0, 3.0), b"1")


def log_uniform(lo: float, hi: float):
    """Positive floats spread evenly in log between lo and hi."""
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: 10.0 ** e)


def hostile(good):
    """Mostly ``good`` values, sometimes edge floats or wrongly typed junk."""
    return st.one_of(good, good, good, st.sampled_from(EDGE_FLOATS), st.sampled_from(JUNK),
                     st.floats(allow_nan=True, allow_infinity=True))


def pair(good):
    return st.tuples(good, good).map(sorted).map(tuple)


# EnvConfig fields -> strategies of plausible and hostile values
ENV_FIELDS = {
    "n_actuators": hostile(st.integers(1, 8)) | st.integers(-3, 2000),
    "spacing": hostile(log_uniform(1e-5, 5e-3)),
    "shape": st.sampled_from(["gaussian", "sinusoidal", "clamped_beam", "square", 3, None]),
    "wavelength": hostile(log_uniform(1e-5, 1e-2)),
    "start_offset": hostile(log_uniform(1e-6, 1e-3)),
    "start_jitter": hostile(st.just(0.0) | log_uniform(1e-7, 1e-4)),
    "target_range": hostile(pair(log_uniform(1e-5, 0.2))) | st.just([1e-3]),
    "tolerance": hostile(log_uniform(1e-10, 1e-2)),
    "freq_range": hostile(pair(log_uniform(50.0, 2e4))),
    "stroke_range": hostile(pair(log_uniform(1e-6, 5e-4))),
    "delay_range": hostile(pair(st.just(0.0) | log_uniform(1e-6, 10.0))),
    "progress_scale": hostile(st.none() | log_uniform(1e-10, 1e-1)),
    "time_cost": hostile(st.just(0.0) | log_uniform(1e-3, 1e6)),
    "success_bonus": hostile(log_uniform(1e-3, 1e6)),
    "detach_penalty": hostile(log_uniform(1e-3, 1e6)),
    "max_time": hostile(log_uniform(1e-4, 1e6)),
    "stop_at_target": hostile(st.booleans()),
    "mode": st.sampled_from(["event", "karnopp", "euler"]),
    "kinematics": st.sampled_from(["reduced", "exact", "seed", "other"]),
    "dt": hostile(log_uniform(1e-7, 1e-3)),
    "max_steps": st.sampled_from([10_000_000, 1, 1000, 0, -5, 2.5, True, 10 ** 13]),
    "action_noise": hostile(st.just(0.0) | st.floats(0.0, 1.2)),
    "friction_factor_range": hostile(pair(log_uniform(0.05, 20.0))) | st.just([1.0]),
    "mass_factor_range": hostile(pair(log_uniform(0.05, 20.0))),
}

env_overrides = st.dictionaries(st.sampled_from(sorted(ENV_FIELDS)), st.none(), max_size=4).flatmap(
    lambda d: st.fixed_dictionaries({k: ENV_FIELDS[k] for k in d}))
