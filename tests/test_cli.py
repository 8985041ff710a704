"""The console script: one JSON object on stdout, clear errors."""
import json
import subprocess
import sys


def run(*args):
    return subprocess.run([sys.executable, "-m", "microconveyor_env.cli", *args],
                          capture_output=True, text=True, timeout=300)


def test_contact_json_and_plot(tmp_path):
    png = tmp_path / "contact.png"
    r = run("contact", "--preset", "seed", "--json", "--plot", str(png))
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    for key in ("pull_off_force_N", "pull_off_separation_m", "separation_at_weight_m",
                "friction_at_weight_N", "balance_separation_m", "asperity_radius_m",
                "critical_interference_m"):
        assert isinstance(out[key], float) and out[key] > 0
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"


def test_error_is_json_with_nonzero_status():
    r = run("contact", "--preset", "nope", "--json")
    assert r.returncode == 2
    assert "unknown preset" in json.loads(r.stdout)["error"]
