"""A policy folder is checked whole, and nothing about it is guessed: every file the loader needs
is listed with its sha256 in its metadata (a DAgger folder's statistics included), a policy that
does not say which env it was trained on is evaluated only on an env the caller names, the
network must be the one its metadata and zip describe, the metadata's own keys must agree, and
both forward passes refuse an overflowing network. ``evaluate`` runs on the env the policy was
trained on, randomisation included, from the CLI and from Python alike."""
import io
import json
import shutil
import zipfile

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from agents.rl.artefacts.checkpoint import sha256  # noqa: E402
from agents.rl.artefacts.policy_files import PolicyError, load_policy  # noqa: E402
from agents.rl.artefacts.shipped import shipped_path, shipped_policies  # noqa: E402
from support.cli import run_cli  # noqa: E402


def _copy(tmp_path, name, env_id, as_name=None):
    dst = tmp_path / (as_name or f"{env_id}-{name}")
    shutil.copytree(shipped_path(name, env_id), dst)
    return dst


def _meta(folder):
    return json.loads((folder / "metadata.json").read_text())


def _write_meta(folder, meta):
    (folder / "metadata.json").write_text(json.dumps(meta))


def _rehash(folder):
    meta = _meta(folder)
    meta["files"] = {n: sha256(folder / n) for n in ("model.zip", "normalization.json")
                     if (folder / n).is_file()}
    _write_meta(folder, meta)


def _cli(*args):
    """A command in this process (tests/cli start the console script's processes)."""
    return run_cli(*args)


def _refused(r, *words):
    """The CLI refused in one line naming ``words``."""
    assert r.returncode == 2, r.stdout + r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    for w in words:
        assert w in lines[0], lines[0]


def _edit_weights(zip_path, edit):
    """Rewrite ``policy.pth`` (and, through ``edit``'s return, the data JSON) of an SB3 zip:
    ``edit(state, data)`` changes the tensors and data in place."""
    import torch

    with zipfile.ZipFile(zip_path) as zf:
        items = {n: zf.read(n) for n in zf.namelist()}
    state = torch.load(io.BytesIO(items["policy.pth"]), map_location="cpu", weights_only=True)
    data = json.loads(items["data"])
    edit(state, data)
    buf = io.BytesIO()
    torch.save(state, buf)
    items["policy.pth"], items["data"] = buf.getvalue(), json.dumps(data).encode()
    with zipfile.ZipFile(zip_path, "w") as zf:
        for n, b in items.items():
            zf.writestr(n, b)
    if (zip_path.parent / "metadata.json").is_file():
        _rehash(zip_path.parent)


# --- every file the loader needs is listed ---------------------------------------------------

@pytest.mark.parametrize("env_id", ["MicroConveyor-v1", "MicroPositioner-v0"])
def test_a_dagger_folder_without_its_statistics_is_refused(tmp_path, env_id):
    """The DAgger student reads normalised observations (its metadata says trained_by dagger
    and nothing of raw observations): without normalization.json, listed or not, it would act
    on raw observations (0 % success), so the folder is refused."""
    folder = _copy(tmp_path, "dagger", env_id)
    (folder / "normalization.json").unlink()
    _rehash(folder)                                   # files: model.zip only
    assert set(_meta(folder)["files"]) == {"model.zip"}
    with pytest.raises(PolicyError, match="has no normalization.json"):
        load_policy(folder)
    _refused(_cli("evaluate", "--policy", str(folder), "--targets", "2"),
             "has no normalization.json")


def test_the_statistics_must_be_listed_even_when_present(tmp_path):
    folder = _copy(tmp_path, "dagger", "MicroConveyor-v1")
    meta = _meta(folder)
    del meta["files"]["normalization.json"]
    _write_meta(folder, meta)
    with pytest.raises(PolicyError, match="does not list normalization.json in files"):
        load_policy(folder)


@pytest.mark.parametrize("name, env_id", [("dagger", "MicroConveyor-v1"),
                                          ("ppo", "MicroConveyor-v1")])
def test_metadata_without_files_is_refused(tmp_path, name, env_id):
    folder = _copy(tmp_path, name, env_id)
    meta = _meta(folder)
    del meta["files"]
    _write_meta(folder, meta)
    with pytest.raises(PolicyError, match="lists no files with their sha256"):
        load_policy(folder)
    _refused(_cli("evaluate", "--policy", str(folder), "--targets", "2"),
             "lists no files with their sha256")


def test_raw_observations_are_said_explicitly_and_then_no_statistics_may_lie_unlisted(tmp_path):
    """A DAgger folder saying its policy reads raw observations needs no statistics; the
    statistics left beside it, unlisted, make the folder ambiguous and are refused."""
    from agents.rl.artefacts.policy_files import reads_raw_observations, required_files

    folder = _copy(tmp_path, "dagger", "MicroConveyor-v1")
    meta = _meta(folder)
    assert not reads_raw_observations(meta)
    assert required_files(meta) == ("model.zip", "normalization.json")
    meta["hyperparams"]["normalize"] = None
    del meta["files"]["normalization.json"]
    _write_meta(folder, meta)
    assert reads_raw_observations(meta) and required_files(meta) == ("model.zip",)
    with pytest.raises(PolicyError, match="reads raw observations, but .* unlisted"):
        load_policy(folder)
    (folder / "normalization.json").unlink()
    assert load_policy(folder).normalizer is None


def test_every_shipped_folder_lists_what_its_loader_needs():
    from agents.rl.artefacts.policy_files import required_files

    for env_id, names in shipped_policies().items():
        for name in names:
            meta = _meta(shipped_path(name, env_id))
            assert set(required_files(meta)) <= set(meta["files"]), (env_id, name)
            assert load_policy(shipped_path(name, env_id)).normalizer is not None


# --- the env a policy was trained on is never guessed ----------------------------------------

def test_a_policy_without_metadata_needs_its_env_named(tmp_path):
    from microconveyor_env.envs import env_config

    folder = _copy(tmp_path, "dagger", "MicroConveyor-v1")
    (folder / "metadata.json").unlink()
    bare = tmp_path / "bare.zip"
    shutil.copy(folder / "model.zip", bare)
    for path in (folder, folder / "model.zip", bare):
        with pytest.raises(PolicyError, match="has no metadata.json: nothing says which env"):
            load_policy(path)
    _refused(_cli("evaluate", "--policy", str(folder), "--targets", "2"),
             "has no metadata.json", "--env ID")
    _refused(_cli("evaluate", "--policy", str(bare), "--targets", "2"), "--env ID")
    # named: the env id, or the config of its scene
    pol = load_policy(folder, env_id="MicroConveyor-v1")
    assert pol.env_id == "MicroConveyor-v1" and pol.normalizer is not None
    assert load_policy(folder, env_config("MicroConveyor-v1")).env_id == "MicroConveyor-v1"
    r = _cli("evaluate", "--policy", str(folder), "--env", "MicroConveyor-v1", "--targets", "2",
             "--json")
    assert r.returncode == 0, r.stdout + r.stderr
    assert json.loads(r.stdout)["env_id"] == "MicroConveyor-v1"


def test_metadata_naming_no_env_id_needs_it_named(tmp_path):
    folder = _copy(tmp_path, "ppo", "MicroConveyor-v0")
    meta = _meta(folder)
    del meta["env_id"]
    _write_meta(folder, meta)
    with pytest.raises(PolicyError, match="names no env_id: nothing says which env"):
        load_policy(folder)
    assert load_policy(folder, env_id="MicroConveyor-v0").env_id == "MicroConveyor-v0"


def test_an_env_id_other_than_the_policys_is_refused():
    with pytest.raises(PolicyError, match="trained on MicroConveyor-v1, not MicroConveyor-v0"):
        load_policy(shipped_path("dagger", "MicroConveyor-v1"), env_id="MicroConveyor-v0")


# --- the metadata's keys agree with each other and with the zip ------------------------------

@pytest.mark.parametrize("edit, message", [
    (lambda m: m.update(inference="fast"), "inference 'fast' is not one this loader knows"),
    (lambda m: m.update(inference="Portable"), "inference 'Portable' is not one"),
    (lambda m: m["hyperparams"].update(env_id="MicroConveyor-v0"),
     "env_id 'MicroConveyor-v1' and hyperparams.env_id 'MicroConveyor-v0' disagree"),
    (lambda m: m.update(env_kwargs={"action_noise": 0.01}),
     "env_kwargs .* and hyperparams.env_kwargs .* disagree"),
    (lambda m: m["hyperparams"].update(net_arch=[64, 64, 64]),
     r"hidden layers \[64, 64\], but .*hyperparams.net_arch says \[64, 64, 64\]"),
    (lambda m: m.update(trained_by=""), "trained_by must name the training method"),
])
def test_metadata_that_contradicts_itself_or_the_model_is_refused(tmp_path, edit, message):
    folder = _copy(tmp_path, "dagger", "MicroConveyor-v1")
    meta = _meta(folder)
    edit(meta)
    _write_meta(folder, meta)
    with pytest.raises(PolicyError, match=message):
        load_policy(folder)


def test_a_ppo_folders_policy_kwargs_net_arch_is_compared(tmp_path):
    folder = _copy(tmp_path, "ppo", "MicroConveyor-v1")
    meta = _meta(folder)
    meta["hyperparams"]["policy_kwargs"]["net_arch"] = {"pi": [128], "vf": [128, 128]}
    _write_meta(folder, meta)
    with pytest.raises(PolicyError, match=r"policy_kwargs.net_arch says \[128\]"):
        load_policy(folder)


def _add_layer(state, data):
    import torch

    p = "mlp_extractor.policy_net"
    n = max(int(k.split(".")[2]) for k in state if k.startswith(p + "."))
    state[f"{p}.{n + 2}.weight"] = torch.eye(64, dtype=torch.float32)
    state[f"{p}.{n + 2}.bias"] = torch.zeros(64, dtype=torch.float32)


def _drop_layer(state, data):
    p = "mlp_extractor.policy_net"
    del state[f"{p}.2.weight"], state[f"{p}.2.bias"]


@pytest.mark.parametrize("change", [_add_layer, _drop_layer])
def test_a_layer_added_or_removed_in_the_zip_is_refused(tmp_path, change):
    """The v1 dagger policy (portable inference) with a layer more or less in policy.pth: the
    zip's own net_arch refuses it; with the zip's net_arch edited to match, the metadata's."""
    folder = _copy(tmp_path, "dagger", "MicroConveyor-v1")
    _edit_weights(folder / "model.zip", change)
    with pytest.raises(PolicyError, match="its data's policy_kwargs.net_arch says"):
        load_policy(folder)

    def and_net_arch(state, data):
        widths = [64, 64, 64] if change is _add_layer else [64]
        data["policy_kwargs"]["net_arch"]["pi"] = widths

    _edit_weights(folder / "model.zip", and_net_arch)
    with pytest.raises(PolicyError, match="hyperparams.net_arch says"):
        load_policy(folder)


def test_portable_inference_needs_a_network_it_can_compute(tmp_path):
    folder = _copy(tmp_path, "ppo", "MicroConveyor-v1")
    meta = _meta(folder)
    meta["inference"] = "portable"
    _write_meta(folder, meta)
    pol = load_policy(folder)   # a Tanh network on Box observations: computable
    obs = pol.normalizer.mean[None].astype(np.float32)
    np.testing.assert_array_equal(pol.act(obs), pol.actor.predict_portable(pol.normalizer(obs)))
    pol.actor.activation = "GELU"
    with pytest.raises(PolicyError, match="portable inference takes"):
        pol.act(obs)


# --- overflow: both forward passes refuse it --------------------------------------------------

def _overflowing(state, data):
    """A first layer whose output overflows float32 on an observation whose first normalised
    component is >= 1: weight column 0 and biases at 3e38 (finite float32 values)."""
    w = state["mlp_extractor.policy_net.0.weight"]
    w.zero_()
    w[:, 0] = 3e38
    state["mlp_extractor.policy_net.0.bias"].fill_(3e38)


@pytest.mark.parametrize("inference", ["portable", None])
def test_an_overflowing_network_is_refused_by_both_forward_passes(tmp_path, inference):
    folder = _copy(tmp_path, "dagger", "MicroConveyor-v1")
    _edit_weights(folder / "model.zip", _overflowing)
    meta = _meta(folder)
    meta.pop("inference")
    if inference:
        meta["inference"] = inference
    _write_meta(folder, meta)
    pol = load_policy(folder)
    obs = (pol.normalizer.mean + 2 * np.sqrt(pol.normalizer.var))[None].astype(np.float32)
    with pytest.raises(PolicyError, match="leaves float32's finite range"):
        pol.act(obs)
    normed = pol.normalizer(obs)
    from agents.rl.artefacts.actor_net import ActorOverflowError

    for predict in (pol.actor.predict, pol.actor.predict_portable):
        with pytest.raises(ActorOverflowError, match="mlp_extractor.policy_net.0"):
            predict(normed)
    # an observation it can compute: both passes act, and agree
    low = pol.normalizer.mean[None].astype(np.float32)
    low[0, 0] = pol.normalizer.mean[0] - 0.5 * np.sqrt(pol.normalizer.var[0])
    n = pol.normalizer(low)
    np.testing.assert_allclose(pol.actor.predict(n), pol.actor.predict_portable(n), atol=1e-5)


# --- one default env for evaluation, from the CLI and from Python ----------------------------

def test_evaluate_defaults_to_the_trained_env_from_the_cli_and_python():
    """The positioner's dagger policy was trained under per-episode randomisation: evaluate()
    and ``microconveyor evaluate --policy`` (with or without --env) run that env, as its
    recorded ``evaluation`` (config "trained") did."""
    from agents.rl.evaluation.evaluate import evaluate, fixed_targets, rollout, summarize
    from agents.rl.artefacts.policy_files import policy_scene

    env_id, folder = "MicroPositioner-v0", shipped_path("dagger", "MicroPositioner-v0")
    pol = load_policy(folder)
    trained = policy_scene(pol.metadata)
    assert trained.randomised and pol.trained_config == trained and not pol.config.randomised
    n, seed = 12, 12345
    py = evaluate(pol, n, seed)
    ref = rollout(pol, fixed_targets(trained, n, seed), trained, seed=seed)
    assert py["median_abs_error_m"] == summarize(ref, trained.tolerance)["median_abs_error_m"]
    nominal = evaluate(pol, n, seed, config=pol.config)
    assert nominal["median_abs_error_m"] != py["median_abs_error_m"]
    for extra in ((), ("--env", env_id)):
        r = _cli("evaluate", "--policy", str(folder), "--targets", str(n), "--seed", str(seed),
                 "--json", *extra)
        assert r.returncode == 0, r.stdout + r.stderr
        cli = json.loads(r.stdout)
        assert cli["median_abs_error_m"] == py["median_abs_error_m"], extra
        assert cli["success_rate"] == py["success_rate"], extra
        assert cli["env_kwargs"] == cli["trained_env_kwargs"] == pol.metadata["env_kwargs"]


# --- the metadata says the model format (algo) and the method (trained_by) -------------------

def test_algo_names_the_model_format_and_trained_by_the_method():
    from agents.rl.artefacts.model_zip import read_data
    from agents.rl.artefacts.sb3_files import algo_of

    for env_id, names in shipped_policies().items():
        for name in names:
            folder = shipped_path(name, env_id)
            meta = _meta(folder)
            assert meta["algo"] == algo_of(read_data(folder / "model.zip"))
            if name.startswith("dagger"):
                assert meta["trained_by"] == "dagger", (env_id, name)
            if meta.get("trained_by", meta["algo"]) == "dagger":
                # imitation (v1's staged recipe too): a PPO-format network with its record
                assert meta["algo"] == "ppo" and meta["expert"] and meta["rounds"], (env_id, name)
            else:
                assert meta.get("trained_by", meta["algo"]) == meta["algo"], (env_id, name)
