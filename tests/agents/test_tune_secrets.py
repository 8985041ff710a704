"""What `tune` and `train-seeds` print and refuse before touching a study: a storage's secrets
(its URL's password, password parameters, also in a URL that does not parse) appear in no error,
progress line or result; bad seeds are one line before any study or training is written."""
from __future__ import annotations

import json

import pytest

pytest.importorskip("stable_baselines3")
pytest.importorskip("optuna")

from agents.rl.tuning.settings import TuneSettings  # noqa: E402
from agents.rl.tuning.storage import mask, shown  # noqa: E402

SECRET = "SECRET"
TINY = ["--trials", "1", "--steps", "64", "--eval-freq", "0", "--eval-targets", "5",
        "--env", "MicroConveyor-v0"]


@pytest.mark.parametrize("url, shows", [
    ("postgresql://u@127.0.0.1:1/db?password=SECRET", "postgresql://u@127.0.0.1:1/db?password=***"),
    ("postgresql://u:SECRET@127.0.0.1:1/db", "postgresql://u:***@127.0.0.1:1/db"),
    ("postgres ql://u:SECRET@host/db", "postgres ql://u:***@host/db"),
    ("postgresql://u:SECRET@host:notaport/db", "postgresql://u:***@host:notaport/db"),
    ("mysql+pymysql://u@h/db?sslpassword=SECRET&charset=utf8", None),
    ("postgresql://u:pa%40SECRET@h/db", "postgresql://u:***@h/db"),
    ("host=h password=SECRET dbname=x", "host=h password=*** dbname=x"),
    ("sqlite:////tmp/x.db", "sqlite:////tmp/x.db"),
])
def test_a_storage_url_is_shown_without_its_secrets(url, shows):
    text = shown(url)
    assert SECRET not in text
    if shows is not None:
        assert text == shows
    assert SECRET not in mask(f"could not connect to {url}", url)


def test_a_secret_quoted_by_itself_is_masked_too():
    """A driver's message that quotes the password alone (percent-decoded)."""
    url = "postgresql://u:pa%40SECRET@h/db"
    assert mask("password 'pa@SECRET' refused for u", url) == "password '***' refused for u"
    assert mask("token SECRETISH", "postgresql://h/db?password=SECRETISH") == "token ***"
    # a masked text stays as it is (the clause after a masked value keeps its colon)
    text = "cannot open postgresql://u@h/db?password=***: OperationalError: refused"
    assert mask(text, "postgresql://u@h/db?password=SECRET") == text
    assert mask("sslpassword=SEC:RET&x=1; (password=abc).") == "sslpassword=***&x=1; (password=***)."


def _tune(capsys, url: str, tmp_path, *extra: str) -> tuple[int, str, str]:
    from microconveyor_env.cli import main

    status = main(["tune", "--storage", url, "--out", str(tmp_path / "t"), *TINY, *extra])
    cap = capsys.readouterr()
    return status, cap.out, cap.err


@pytest.mark.parametrize("url", ["postgresql://u@127.0.0.1:1/db?password=SECRET",
                                 "postgresql://u:SECRET@127.0.0.1:1/db?sslpassword=SECRET",
                                 "postgres ql://u:SECRET@host/db",
                                 "postgresql://u:SECRET@host:notaport/db"])
def test_tune_never_prints_a_storage_secret(tmp_path, capsys, url):
    for extra in ((), ("--json",)):
        status, out, err = _tune(capsys, url, tmp_path, *extra)
        assert status == 2 and len(err.strip().splitlines()) == 1, err
        assert SECRET not in out + err, out + err
        assert "ValueError: cannot open the Optuna storage " in err and "***" in err
        if "?password=" in url:
            assert "/db?password=***: OperationalError: " in err
        if extra:
            assert "storage" in json.loads(out)["error"]


def test_tune_results_and_progress_lines_never_show_a_storage_secret(tmp_path, capsys,
                                                                    monkeypatch):
    """A study run to the end: its result (text and JSON) and the failure line carry no secret,
    whatever the trials' errors quote."""
    import agents.rl.tuning.tune as tune_mod
    from agents.rl.tuning.workers import _log

    url = "postgresql://tuner@db.example/optuna?password=SECRET"

    def fake(settings):
        assert settings.storage == url
        return {"study": "s", "storage": url, "trials": 1, "states": {"fail": 1},
                "workers": {"h:1": 1}, "best": None, "env_id": "MicroConveyor-v0",
                "this_run": [{"number": 0, "state": "FAIL", "value": None, "worker": "h:1",
                              "error": f"OperationalError: {url} password=SECRET"}],
                "failed": [{"number": 0, "worker": "h:1",
                            "error": f"OperationalError: {url} password=SECRET"}],
                "died": [], "heartbeat_s": 60, "failed_stale": [], "wall_time_s": 1.0}

    monkeypatch.setattr(tune_mod, "tune", fake)
    for extra in ((), ("--json",)):
        status, out, err = _tune(capsys, url, tmp_path, *extra)
        assert status == 2 and SECRET not in out + err, out + err
        assert "trial 0" in err and "***" in out
    _log(0, url)(f"trial 0 failed OperationalError: {url}")
    err = capsys.readouterr().err
    assert err.startswith("worker 0: trial 0 failed") and SECRET not in err


@pytest.mark.parametrize("option", ["--seed", "--sampler-seed"])
def test_tune_refuses_a_bad_seed_before_touching_the_study(tmp_path, capsys, option):
    from microconveyor_env.cli import main

    status = main(["tune", "--out", str(tmp_path / "t"), *TINY, option, "-1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and "a seed is a whole number in [0, " in err[0], err
    assert not (tmp_path / "t").exists()   # no study (optuna.db), no trial
    with pytest.raises(ValueError, match="seed must be a whole number"):
        TuneSettings(out=tmp_path / "t", seed=-1)
    with pytest.raises(ValueError, match="sampler_seed must be a whole number"):
        TuneSettings(out=tmp_path / "t", sampler_seed=2**31)


def test_train_seeds_refuses_a_bad_seed_in_one_line(tmp_path, capsys):
    from microconveyor_env.cli import main

    status = main(["train-seeds", "--seeds", "0", "-1", "--out", str(tmp_path / "s"),
                   "--steps", "64", "--json"])
    cap = capsys.readouterr()
    assert status == 2 and len(cap.err.strip().splitlines()) == 1, cap.err
    assert "Traceback" not in cap.err and len(cap.out.strip().splitlines()) == 1
    assert "a seed is a whole number" in json.loads(cap.out)["error"]
    assert not (tmp_path / "s").exists()


def test_tune_refuses_a_best_file_it_would_write_through_a_link(tmp_path, capsys):
    from microconveyor_env.cli import main

    victim = tmp_path / "victim.yml"
    victim.write_text("keep")
    (tmp_path / "best.yml").symlink_to(victim)
    status = main(["tune", "--out", str(tmp_path / "t"), *TINY, "--best",
                   str(tmp_path / "best.yml")])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and "--best" in err[0] and "symbolic link" in err[0]
    assert victim.read_text() == "keep" and not (tmp_path / "t" / "optuna.db").exists()
