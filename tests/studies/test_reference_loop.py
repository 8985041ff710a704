"""The plain-Python "dissertation's way" baseline ships in the package and agrees with the kernel's
karnopp mode at the same step (the benchmark compares like with like)."""
from microconveyor_env.studies.reference_loop import package_displacement, reference_firing


def test_reference_loop_matches_the_kernels_karnopp_mode(feasibility_preset):
    dt = 1e-5
    ref = reference_firing(feasibility_preset.contact, dt=dt)
    pkg = package_displacement(feasibility_preset.contact, dt=dt, mode="karnopp")
    assert ref["dt_s"] <= dt
    assert abs(ref["displacement_m"] - pkg.displacement_m) < 1e-8
