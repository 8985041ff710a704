"""Hostile contact parameters: a ParameterError naming the field (or, for an in-range combination
the model cannot do, all the contact fields), else a consistent table and finite simulations."""
import math

import numpy as np
from hypothesis import event, example, given, strategies as st

from microconveyor_env.physics import contact_table as ct
from microconveyor_env.physics.materials import ContactParams, ParameterError
from microconveyor_env.physics.schedule import Schedule
from microconveyor_env.physics.simulator import Simulator

from .strategies import hostile, log_uniform

FIELDS = {  # a little beyond the documented ranges on both sides
    "materials__E1": log_uniform(1e7, 1e14), "materials__E2": log_uniform(1e7, 1e14),
    "materials__nu1": st.floats(-0.1, 0.6), "materials__hardness": log_uniform(1e8, 1e12),
    "surface__sigma": log_uniform(1e-10, 1e-5), "surface__psi": log_uniform(0.03, 3e3),
    "surface__beta": log_uniform(1e-7, 1e4), "surface__dgamma": log_uniform(1e-7, 10.0),
    "surface__eps": log_uniform(1e-11, 1e-8), "part__mass": log_uniform(1e-12, 1.0),
    "part__area": log_uniform(1e-12, 1.0), "friction_scale": log_uniform(1e-7, 1e7),
}
DOCUMENTED = {  # the validated ranges: mostly draw from these
    "materials__E1": log_uniform(1e8, 1e13), "materials__E2": log_uniform(1e8, 1e13),
    "materials__nu1": st.floats(0.0, 0.49), "materials__hardness": log_uniform(1e9, 1e11),
    "surface__sigma": log_uniform(1e-9, 1e-6), "surface__psi": log_uniform(0.1, 1e3),
    "surface__beta": log_uniform(1e-6, 1e3), "surface__dgamma": log_uniform(1e-6, 2.0),
    "surface__eps": log_uniform(1e-10, 3e-9), "part__mass": log_uniform(1e-12, 1e-3),
    "part__area": log_uniform(1e-12, 1e-2), "friction_scale": log_uniform(1e-6, 1e6),
}
changes = st.dictionaries(st.sampled_from(sorted(FIELDS)), st.none(), min_size=1, max_size=3).flatmap(
    lambda d: st.fixed_dictionaries({k: st.one_of(DOCUMENTED[k], DOCUMENTED[k], hostile(FIELDS[k]))
                                     for k in d}))


def _label(key: str) -> str:
    group, _, name = key.rpartition("__")
    return f"{group.capitalize()}.{name}" if group else f"ContactParams.{name}"


@given(kw=changes)
@example(kw={"surface__psi": 0.001})        # used to allocate 62 GiB
@example(kw={"surface__dgamma": 100.0})     # "net load does not change sign"
@example(kw={"surface__sigma": "2e-8"})     # numeric strings are not numbers
@example(kw={"part__mass": True})
@example(kw={"part__mass": 0.5})            # weight beyond the table
@example(kw={"surface__sigma": 1e-9, "surface__dgamma": 0.1, "surface__psi": 0.5})  # smooth MEMS
@example(kw={"surface__psi": 0.1, "surface__sigma": 2e-9})   # elastic: omega_c* = 100
@example(kw={"surface__psi": 100.0})        # asperity radius below sigma: outside KE (2002)
def test_contact_parameters_give_clear_errors_or_finite_physics(kw):
    try:
        params = ContactParams().replace(**kw)
        table = ct.ContactTable(params)
        sim = Simulator(params)
    except ParameterError as exc:
        msg = str(exc)
        named = [k for k in kw if _label(k) in msg]
        assert named or "no contact table" in msg, msg
        event("refused: " + ("field" if named else "combination"))
        return
    event("accepted")
    assert ct.consistent(table.base)
    assert all(math.isfinite(v) for v in table.report().values() if isinstance(v, float))
    try:
        r = sim.simulate(Schedule.single(700.0, 150e-6), x0=0.125e-3)
    except ValueError as exc:  # TableRangeError: the stroke would load beyond the table
        assert "contact table" in str(exc)
        return
    assert np.isfinite([r.final_position_m, r.final_velocity_m_s, r.end_time_s]).all()
