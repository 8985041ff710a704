"""``microconveyor record`` and ``microconveyor ship`` (agents.rl.artefacts.shipping) leave a
folder that loads: they load (and verify) it before changing anything, write its new metadata
whole with ``files`` recomputed, and refuse a folder that does not load without touching it.
Each runs on a copy of a shipped folder under a temporary ``--root``, its targets cut to two
(``fixed_targets`` patched: the records' own counts take minutes)."""
import json
import shutil

import pytest

pytest.importorskip("stable_baselines3")

from agents.rl.artefacts import shipping  # noqa: E402
from agents.rl.artefacts.checkpoint import META, MODEL, read_meta, sha256, verify_files  # noqa: E402
from agents.rl.artefacts.policy_files import PolicyError, load_policy, required_files  # noqa: E402
from agents.rl.artefacts.shipped import shipped_path  # noqa: E402
from microconveyor_env.cli import main  # noqa: E402


@pytest.fixture
def root(tmp_path, monkeypatch):
    """A folder of policies to record into; every evaluation on at most two targets."""
    real = shipping.fixed_targets
    monkeypatch.setattr(shipping, "fixed_targets", lambda cfg, n, seed: real(cfg, min(n, 2), seed))
    return tmp_path / "policies"


def _copy(env_id, name, root):
    dst = root / env_id / name
    shutil.copytree(shipped_path(name, env_id), dst)
    return dst


def _loads_whole(folder):
    """The folder loads, and its ``files`` list every file the loader needs with its hash."""
    load_policy(folder)
    meta = read_meta(folder)
    verify_files(folder, meta)
    assert set(required_files(meta)) <= set(meta["files"])
    for name, digest in meta["files"].items():
        assert sha256(folder / name) == digest
    return meta


def _snapshot(env_id, name):
    src = shipped_path(name, env_id)
    return {p.name: p.read_bytes() for p in sorted(src.iterdir()) if p.is_file()}


@pytest.mark.parametrize("env_id,name", [("MicroConveyor-v0", "ppo"),
                                         ("MicroConveyor-v1", "dagger"),
                                         ("MicroPositioner-v0", "dagger")])
def test_record_leaves_a_folder_that_loads(env_id, name, root, capsys):
    before = _snapshot(env_id, name)
    folder = _copy(env_id, name, root)
    assert main(["record", f"{env_id}/{name}", "--root", str(root), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["recorded"][f"{env_id}/{name}"]["evaluation"]["n_targets"] == 2
    meta = _loads_whole(folder)
    assert meta["evaluation"]["n_targets"] == 2 and meta["format"] == 2
    assert meta["evaluation_provenance"]["command"] == f"microconveyor record {env_id}/{name}"
    episodes = json.loads((folder / "episodes.json").read_text())
    assert set(episodes) == \
        {k for k in meta if k.startswith("evaluation") and k != "evaluation_provenance"}
    # a new record carries the placement times and the tight radii, its episodes their times
    assert {"median_placement_time_s", "p90_placement_time_s", "success_rate_5um",
            "success_rate_10um", "success_rate_20um"} <= set(meta["evaluation"])
    assert len(episodes["evaluation"]["time_s"]) == 2
    assert _snapshot(env_id, name) == before   # the shipped folder itself untouched


def test_plane_records_leave_folders_that_load(root):
    before = {e: _snapshot(e, "ppo") for e in ("MicroConveyor2D-v0", "MicroConveyor2D-v1")}
    v0 = _copy("MicroConveyor2D-v0", "ppo", root)
    v0_record = shipping.record("MicroConveyor2D-v0", "ppo", root)["evaluation"]
    assert v0_record["n_targets"] == 2 and "median_placement_time_s" in v0_record
    _loads_whole(v0)
    v1 = _copy("MicroConveyor2D-v1", "ppo", root)
    out = shipping.record("MicroConveyor2D-v1", "ppo", root)
    assert out["evaluation"]["n_targets"] == 2 == out["evaluation_nominal"]["n_targets"]
    _loads_whole(v1)
    assert {e: _snapshot(e, "ppo") for e in before} == before


def test_record_without_names_records_every_policy_under_the_root(root, capsys):
    _copy("MicroConveyor-v0", "ppo", root)
    _copy("MicroConveyor2D-v0", "ppo", root)
    assert main(["record", "--root", str(root), "--json"]) == 0
    assert set(json.loads(capsys.readouterr().out)["recorded"]) == \
        {"MicroConveyor-v0/ppo", "MicroConveyor2D-v0/ppo"}


def test_a_folder_that_does_not_load_is_refused_untouched(root, capsys):
    for env_id in ("MicroConveyor-v0", "MicroConveyor2D-v0"):
        folder = _copy(env_id, "ppo", root)
        (folder / MODEL).write_bytes((folder / MODEL).read_bytes() + b"\0")   # not the hashed file
        meta_before = (folder / META).read_bytes()
        with pytest.raises(PolicyError, match="sha256"):
            shipping.record(env_id, "ppo", root)
        assert main(["record", f"{env_id}/ppo", "--root", str(root)]) == 2
        assert "sha256" in capsys.readouterr().err
        assert (folder / META).read_bytes() == meta_before


def test_shipping_a_run_writes_a_folder_that_loads(tmp_path, root, capsys):
    """``ship RUN ENV/NAME`` (a new name, then over an existing one) on the line and the plane:
    the shipped folder loads after the copy and after its records."""
    run = tmp_path / "run"
    shutil.copytree(shipped_path("ppo", "MicroConveyor-v0"), run)
    assert main(["ship", str(run), "MicroConveyor-v0/new", "--root", str(root), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["folder"] == str(root / "MicroConveyor-v0" / "new")
    new = root / "MicroConveyor-v0" / "new"
    assert _loads_whole(new)["evaluation_fresh"]["n_targets"] == 2
    old = _copy("MicroConveyor-v0", "ppo_randomised", root)
    shipping.ship(run, "MicroConveyor-v0", "ppo_randomised", root)   # over an existing folder
    assert _loads_whole(old)["files"][MODEL] == sha256(run / MODEL)
    plane_run = tmp_path / "plane_run"
    shutil.copytree(shipped_path("ppo", "MicroConveyor2D-v0"), plane_run)
    dest = shipping.ship(plane_run, "MicroConveyor2D-v0", "ppo", root)
    _loads_whole(dest)
    shipping.record("MicroConveyor2D-v0", "ppo", root)
    _loads_whole(dest)
    with pytest.raises(ValueError, match="MicroConveyor-v1"):
        shipping.ship(run, "MicroConveyor-v1", "other", root)   # a policy of another env
    assert not (root / "MicroConveyor-v1" / "other").exists()
    assert main(["ship", str(run), "MicroConveyor-v1", "--root", str(root)]) == 2   # no NAME
    assert "ENV_ID/NAME" in capsys.readouterr().err
