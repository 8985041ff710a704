"""Human output: SI results shown in the units people read (JSON stays SI)."""
from microconveyor_env.cli.human import format_result, format_value


def test_units_by_key_suffix():
    assert format_value("median_abs_error_m", 6.4e-06) == ("median_abs_error", "6.4 µm")
    assert format_value("final_position_m", 0.009969) == ("final_position", "9.969 mm")
    assert format_value("balance_separation_m", 84.35e-9) == ("balance_separation", "84.35 nm")
    assert format_value("pull_off_force_N", 2.534e-6) == ("pull_off_force", "2.534 µN")
    assert format_value("friction_at_weight_N", 1.754e-8) == ("friction_at_weight", "17.54 nN")
    assert format_value("travel_time_s", 0.0496) == ("travel_time", "49.6 ms")
    assert format_value("slip_acceleration_flat_m_s2", 8.772) == \
        ("slip_acceleration_flat", "8.772 m/s²")
    assert format_value("asperity_density_per_m2", 2.6e11) == ("asperity_density", "2.6e+11 /m²")
    assert format_value("success_rate_50um", 0.97) == ("success_rate_50um", "97.0 %")
    for radius in ("5um", "10um", "20um"):   # every radius an evaluation reports
        assert format_value(f"success_rate_{radius}", 0.3) == (f"success_rate_{radius}", "30.0 %")
    assert format_value("p90_placement_time_s", 0.0565) == ("p90_placement_time", "56.5 ms")
    assert format_value("window_hz", [225.0, 1250.0]) == ("window", "[225 Hz, 1250 Hz]")
    assert format_value("x0_m", 5.4e-20)[1].endswith("nm")     # no bare 5.4e-20
    assert format_value("flag", True) == ("flag", "True")
    assert format_value("window_hz", None) == ("window", "none")


def test_nested_and_long_values_stay_readable():
    text = format_result({"a_m": 1e-3, "sub": {"b_N": 1e-6}, "xs_m": [1e-6] * 20,
                          "rows": [{"x": 1}] * 20})
    lines = text.splitlines()
    assert lines[0].split() == ["a", "1", "mm"]
    assert lines[1] == "sub:" and lines[2].split() == ["b", "1", "µN"]
    assert "20 values: 1 µm ... 1 µm" in lines[3]
    assert "20 entries (--json for all)" in lines[4]


# commands as a user types them without --json (small budgets); their printed output must not be
# a Python dict dump or a raw SI float (issue 23: "0.00015000000000000001", "{'a': ...}")
HUMAN_COMMANDS = [
    ("contact", "--preset", "conveyor"),
    ("simulate", "--freq", "950", "--stroke", "200e-6", "--x0", "-0.125e-3"),
    ("sweep", "--freq", "600:800:100", "--stroke", "200e-6"),
    ("optimize", "--problem", "target", "--target", "2e-3", "--budget", "30"),
    ("evaluate", "--targets", "3"),
    ("evaluate", "--env", "MicroConveyor-v1", "--targets", "3"),
]


def test_every_command_prints_readable_human_output():
    import re
    import subprocess
    import sys

    raw_float = re.compile(r"(?<![\w.])-?\d\.\d{9,}(e-?\d+)?|(?<![\w.])\d\.\d+e-\d\d(?!\s*/)")
    for args in HUMAN_COMMANDS:
        r = subprocess.run([sys.executable, "-m", "microconveyor_env.cli", *args],
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, (args, r.stderr)
        out = r.stdout
        assert out.strip(), args
        assert "{'" not in out and "': " not in out, (args, out)      # no dict dumps
        assert not raw_float.search(out), (args, raw_float.search(out), out)
        assert re.search(r"µm|mm|nm|µN|nN|ms|Hz|%", out), (args, out)  # units people read
