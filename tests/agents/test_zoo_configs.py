"""The shipped rl-zoo3-format configs (configs/ppo*.yml, sac.yml, tqc.yml) run under rl-zoo3 as
they are: rl-zoo3's own experiment manager reads every entry and builds its model (where a key
only this package reads made PPO refuse the v1 entry), and ``python -m rl_zoo3.train`` trains
the v1 PPO entry for one rollout. ``microconveyor train`` reads the same entry plus the file's
``microconveyor`` section: the keys rl-zoo3 reads are the entry's, no more, no fewer."""
import argparse
import subprocess
import sys
from importlib import resources
from pathlib import Path

import pytest
import yaml

pytest.importorskip("rl_zoo3")

from agents.rl.training import hyperparams  # noqa: E402
from microconveyor_env.env_ids import ALL_ENV_IDS  # noqa: E402

CONFIGS = resources.files("microconveyor_env.configs")
FILES = ("ppo", "ppo_quick", "ppo_history", "ppo_randomised", "sac", "tqc")


def _entries() -> list[tuple[str, str]]:
    out = []
    for stem in FILES:
        data = yaml.safe_load((CONFIGS / f"{stem}.yml").read_text())
        out += [(stem, env_id) for env_id in data if env_id in ALL_ENV_IDS]
    return out


def test_every_shipped_file_has_entries():
    assert {stem for stem, _ in _entries()} == set(FILES)
    data = yaml.safe_load((CONFIGS / "ppo.yml").read_text())
    assert set(data) - set(ALL_ENV_IDS) == {hyperparams.PACKAGE_SECTION}


@pytest.mark.parametrize("stem, env_id", _entries())
def test_rl_zoo3_builds_the_model_of_every_shipped_entry(stem, env_id, tmp_path, monkeypatch):
    import microconveyor_env  # noqa: F401 - registers the envs, as --gym-packages does
    from rl_zoo3.exp_manager import ExperimentManager
    from rl_zoo3.utils import ALGOS

    monkeypatch.chdir(tmp_path)
    algo = "ppo" if stem.startswith("ppo") else stem
    path = str(CONFIGS / f"{stem}.yml")
    manager = ExperimentManager(argparse.Namespace(), algo, env_id, str(tmp_path / "logs"),
                                n_timesteps=64, eval_freq=-1, config=path, verbose=0,
                                device="cpu")
    built = manager.setup_experiment()
    assert built is not None
    model, saved = built
    assert isinstance(model, ALGOS[algo])
    model.get_env().close()
    # microconveyor train gets that entry and its package-only keys, nothing else
    zoo, own = hyperparams.split_package_keys(hyperparams.load(path, env_id, stem))
    assert set(saved) == set(zoo)
    assert set(own) <= set(hyperparams.PACKAGE_KEYS)


def test_microconveyor_train_gets_the_same_hyperparameters_as_before():
    """The package keys moved out of the v1 PPO entry into the package section; the entry with
    them is still what the shipped v1 policy was trained with."""
    import json

    raw = yaml.safe_load((CONFIGS / "ppo.yml").read_text())
    assert not set(raw["MicroConveyor-v1"]) & set(hyperparams.PACKAGE_KEYS)

    from agents.rl.artefacts.shipped import shipped_path

    for env_id in ("MicroConveyor-v0", "MicroConveyor-v1"):
        meta = json.loads((shipped_path("ppo", env_id) / "metadata.json").read_text())
        hp = json.loads(json.dumps(hyperparams.load(None, env_id), default=str))
        assert hyperparams.changed_keys(meta["hyperparams"], hp) == []
    v1 = hyperparams.load(None, "MicroConveyor-v1")
    assert v1["exploration_restart"] == {"at": 0.667, "log_std": -2.0}
    assert v1["exploration_shift"] == {"at": 0.833, "by": -1.0}


@pytest.mark.parametrize("section, message", [
    ({"MicroConveyor-v1": {"gamma": 0.9}}, "gamma belong in the entry"),
    ({"MicroConveyor-v1": {"exploration_shift": {"at": 0.5, "by": -1.0}}}, "given both"),
    ([1], "must map env ids"),
])
def test_a_package_section_holds_only_package_keys(tmp_path, section, message):
    entry = {"n_envs": 4, "exploration_shift": {"at": 0.8, "by": -1.0}}
    conf = tmp_path / "ppo.yml"
    conf.write_text(yaml.safe_dump({"MicroConveyor-v1": entry,
                                    hyperparams.PACKAGE_SECTION: section}))
    with pytest.raises(ValueError, match=message):
        hyperparams.load(str(conf), "MicroConveyor-v1")


@pytest.mark.slow   # ~20 s: a real rl-zoo3 training; the entries' models are built above
def test_python_m_rl_zoo3_train_runs_the_shipped_v1_entry(tmp_path):
    conf = str(CONFIGS / "ppo.yml")
    r = subprocess.run([sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env",
                        "MicroConveyor-v1", "--gym-packages", "microconveyor_env",
                        "--conf-file", conf, "-n", "300", "--eval-freq", "-1",
                        "--log-folder", str(tmp_path / "logs"), "--device", "cpu"],
                       capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "total_timesteps | 4096" in r.stdout      # one rollout: 256 envs x 16 steps
    assert list(Path(tmp_path / "logs" / "ppo").glob("MicroConveyor-v1_*/MicroConveyor-v1.zip"))


def test_the_plane_entry_is_the_shipped_plane_policys_recipe():
    """configs/ppo.yml's MicroConveyor2D-v0 entry is what the shipped plane policy was trained
    with (its metadata records the step budget as planned_timesteps, and one torch thread, which
    `microconveyor train` always uses)."""
    import json

    from agents.rl.artefacts.shipped import shipped_path

    meta = json.loads((shipped_path("ppo", "MicroConveyor2D-v0") / "metadata.json").read_text())
    hp = json.loads(json.dumps(hyperparams.load(None, "MicroConveyor2D-v0"), default=str))
    assert hyperparams.changed_keys(meta["hyperparams"], hp) == ["n_timesteps", "torch_threads"]
    assert hp["n_timesteps"] == meta["planned_timesteps"] and meta["hyperparams"]["torch_threads"] == 1
