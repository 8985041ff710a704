"""The scripts that (re-)record and ship the shipped policies leave a folder that loads: they
load (and verify) it before changing anything, write its new metadata whole with ``files``
recomputed, and refuse a folder that does not load without touching it. Each runs on a copy of
a shipped folder in a temporary folder (``shipped_path`` pointed there), on two targets."""
import importlib.util
import json
import shutil
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")

from agents.rl.artefacts.checkpoint import META, MODEL, read_meta, sha256, verify_files  # noqa: E402
from agents.rl.artefacts.policy_files import PolicyError, load_policy, required_files  # noqa: E402
from agents.rl.artefacts.shipped import shipped_path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = ROOT / "scripts"


def _script(name, monkeypatch, tmp_path):
    """The script ``name`` as a module, its targets cut to two and ``shipped_path`` pointing
    under ``tmp_path / "policies"`` (never at the shipped folders)."""
    monkeypatch.syspath_prepend(str(SCRIPTS))
    spec = importlib.util.spec_from_file_location(f"_record_{name}", SCRIPTS / f"{name}.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    real = mod.fixed_targets
    monkeypatch.setattr(mod, "fixed_targets", lambda cfg, n, seed: real(cfg, min(n, 2), seed))
    monkeypatch.setattr(mod, "shipped_path",
                        lambda name=None, env_id="": tmp_path / "policies" / env_id / name)
    return mod


def _copy(env_id, name, tmp_path):
    dst = tmp_path / "policies" / env_id / name
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
def test_record_shipped_evaluations_leaves_a_folder_that_loads(env_id, name, tmp_path,
                                                                monkeypatch):
    before = _snapshot(env_id, name)
    mod = _script("record_shipped_evaluations", monkeypatch, tmp_path)
    folder = _copy(env_id, name, tmp_path)
    mod.record(env_id, name)
    meta = _loads_whole(folder)
    assert meta["evaluation"]["n_targets"] == 2 and meta["format"] == 2
    assert set(json.loads((folder / "episodes.json").read_text())) == \
        {k for k in meta if k.startswith("evaluation") and k != "evaluation_provenance"}
    assert _snapshot(env_id, name) == before   # the shipped folder itself untouched


def test_plane_records_leave_folders_that_load(tmp_path, monkeypatch):
    before = {e: _snapshot(e, "ppo") for e in ("MicroConveyor2D-v0", "MicroConveyor2D-v1")}
    mod = _script("ship_plane_policy", monkeypatch, tmp_path)
    v0 = _copy("MicroConveyor2D-v0", "ppo", tmp_path)
    assert mod.record(v0)["n_targets"] == 2
    _loads_whole(v0)
    v1 = _copy("MicroConveyor2D-v1", "ppo", tmp_path)
    out = mod.record_randomised(v1)
    assert out["evaluation"]["n_targets"] == 2 == out["evaluation_nominal"]["n_targets"]
    _loads_whole(v1)
    assert {e: _snapshot(e, "ppo") for e in before} == before


def test_a_folder_that_does_not_load_is_refused_untouched(tmp_path, monkeypatch):
    mod = _script("record_shipped_evaluations", monkeypatch, tmp_path)
    folder = _copy("MicroConveyor-v0", "ppo", tmp_path)
    (folder / MODEL).write_bytes((folder / MODEL).read_bytes() + b"\0")   # not the hashed file
    meta_before = (folder / META).read_bytes()
    with pytest.raises(PolicyError, match="sha256"):
        mod.record("MicroConveyor-v0", "ppo")
    assert (folder / META).read_bytes() == meta_before
    plane = _script("ship_plane_policy", monkeypatch, tmp_path)
    v0 = _copy("MicroConveyor2D-v0", "ppo", tmp_path)
    (v0 / MODEL).write_bytes((v0 / MODEL).read_bytes() + b"\0")
    v0_before = (v0 / META).read_bytes()
    with pytest.raises(PolicyError, match="sha256"):
        plane.record(v0)
    assert (v0 / META).read_bytes() == v0_before


def test_shipping_a_run_writes_a_folder_that_loads(tmp_path, monkeypatch):
    """``--ship RUN ENV/NAME`` (a new name, then over an existing one) and the plane's
    ``--run``: the shipped folder loads after the copy and after its records."""
    mod = _script("record_shipped_evaluations", monkeypatch, tmp_path)
    run = tmp_path / "run"
    shutil.copytree(shipped_path("ppo", "MicroConveyor-v0"), run)
    mod.ship(str(run), "MicroConveyor-v0", "new")
    new = tmp_path / "policies" / "MicroConveyor-v0" / "new"
    _loads_whole(new)
    mod.record("MicroConveyor-v0", "new")
    assert _loads_whole(new)["evaluation_fresh"]["n_targets"] == 2
    old = _copy("MicroConveyor-v0", "ppo_randomised", tmp_path)
    mod.ship(str(run), "MicroConveyor-v0", "ppo_randomised")   # over an existing folder
    assert _loads_whole(old)["files"][MODEL] == sha256(run / MODEL)
    plane = _script("ship_plane_policy", monkeypatch, tmp_path)
    plane_run = tmp_path / "plane_run"
    shutil.copytree(shipped_path("ppo", "MicroConveyor2D-v0"), plane_run)
    dest = tmp_path / "plane_dest" / "ppo"
    plane.ship(plane_run, dest)
    _loads_whole(dest)
    plane.record(dest)
    _loads_whole(dest)
    with pytest.raises(SystemExit, match="MicroConveyor-v1"):
        mod.ship(str(run), "MicroConveyor-v1", "other")   # a policy of another env
    assert not (tmp_path / "policies" / "MicroConveyor-v1" / "other").exists()
