"""``microconveyor video``: a GIF or MP4 of one episode of a fixed schedule or of a policy."""
import argparse
import json
import sys

import pytest
from support.cli import run_cli

iio = pytest.importorskip("imageio.v3", reason="videos need imageio (the render extra)")


def run(*args):
    """``microconveyor video`` in this process (what it prints and its status; tests/support/cli.py)."""
    return run_cli("video", *args)


def _frames(path):
    return iio.imread(path, index=None).shape[0]


def test_schedule_gif_in_process(tmp_path, capsys):
    """A fixed schedule's episode (no --policy), the command called in process."""
    from agents.cli import video

    p = argparse.ArgumentParser()
    video._video_args(p)
    p.add_argument("--json", action="store_true")
    gif = tmp_path / "s.gif"
    args = p.parse_args(["--out", str(gif), "--frames-per-stroke", "2", "--env",
                         "MicroConveyor-v0", "--delay", "0.002", "--target", "0.6e-3", "--json"])
    video.cmd_video(args)
    out = json.loads(capsys.readouterr().out)
    assert out["video"] == str(gif) and out["format"] == "gif" and out["actor"] == "fixed schedule"
    assert out["frames"] > out["firings"] + 1 and out["fps"] == 8.0
    assert gif.read_bytes()[:4] == b"GIF8" and _frames(gif) == out["frames"]
    assert out["bytes"] == gif.stat().st_size and out["schedule"]["delay_s"][0] == 0.002


def test_policy_gif_and_human_text(tmp_path):
    pytest.importorskip("stable_baselines3")
    gif = tmp_path / "p.gif"
    r = run("--policy", "shipped", "--target", "1e-3", "--frames-per-stroke", "2", "--out",
            str(gif), "--fps", "5")
    assert r.returncode == 0, r.stderr
    assert "MicroConveyor-v1, policy " in r.stdout and "MicroConveyor-v1/ppo_refined" in r.stdout and " µm)" in r.stdout and " ms simulated" \
        in r.stdout and "at 5 fps" in r.stdout
    n = _frames(gif)
    firings = int(r.stdout.split(" after ")[1].split(" firing")[0])
    assert n > firings + 1


def test_schedule_mp4_json_and_errors(tmp_path):
    pytest.importorskip("imageio_ffmpeg")
    mp4 = tmp_path / "s.mp4"
    r = run("--out", str(mp4), "--frames-per-stroke", "1", "--env-kwargs", "n_actuators:2",
            "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["format"] == "mp4" and out["frames"] == out["firings"] + 1  # one per firing
    assert out["env_id"] == "MicroConveyor-v1" and out["env_kwargs"] == {"n_actuators": 2}
    assert mp4.stat().st_size > 1000 and _frames(mp4) == out["frames"]
    for bad, msg in ((["--out", str(tmp_path / "x.avi")], ".gif or .mp4"),
                     (["--freq", "50", "--out", str(mp4)], "outside the env's range"),
                     (["--policy", str(tmp_path), "--freq", "900"], "not with --policy")):
        r = run(*bad, "--json")
        assert r.returncode == 2 and msg in json.loads(r.stdout)["error"], r.stdout


def test_missing_writer_names_the_extra(monkeypatch):
    from microconveyor_env.cli.base import missing_extra
    from microconveyor_env.envs.core.video import check_writer

    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # import imageio_ffmpeg fails
    with pytest.raises(ModuleNotFoundError, match=r"microconveyor-env\[render\]") as err:
        check_writer("x.mp4")
    assert "microconveyor-env[render]" in missing_extra(err.value)
    assert check_writer("x.gif").suffix == ".gif"  # a GIF needs no ffmpeg


@pytest.mark.parametrize("fps", ["1e-9", "1e9", "0", "nan"])
def test_fps_out_of_range_is_refused_before_any_work(tmp_path, fps):
    """Exit 2 with one line naming --fps and its range, before the episode: an existing file
    is left as it was and nothing is written."""
    gif = tmp_path / "existing.gif"
    gif.write_bytes(b"precious")
    r = run("--fps", fps, "--out", str(gif), "--env-kwargs", "n_actuators:2")
    assert r.returncode == 2, r.stdout
    line = r.stderr.strip()
    assert "\n" not in line and "--fps" in line and "[0.1, 100]" in line, r.stderr
    assert "internal error" not in line
    assert gif.read_bytes() == b"precious" and sorted(tmp_path.iterdir()) == [gif]


def test_a_failed_write_leaves_the_existing_file_and_no_partial_one(tmp_path, monkeypatch):
    import numpy as np

    from microconveyor_env.envs.core import video

    frames = [np.full((8, 8, 3), 60 * k, np.uint8) for k in range(3)]  # distinct: GIF merges
    gif = tmp_path / "existing.gif"
    gif.write_bytes(b"precious")

    def broken(path, *args, **kwargs):  # writes half a file, then fails
        with open(path, "wb") as fh:
            fh.write(b"GIF89a")
        raise OSError("disk full")

    monkeypatch.setattr(iio, "imwrite", broken)
    with pytest.raises(OSError, match="disk full"):
        video.write_video(frames, gif, 10.0)
    assert gif.read_bytes() == b"precious" and sorted(tmp_path.iterdir()) == [gif]
    with pytest.raises(ValueError, match=r"fps = 1000.0 .*\[0.1, 100\]"):
        video.write_video(frames, gif, 1000.0)
    monkeypatch.undo()
    assert video.write_video(frames, gif, 10.0) == gif  # success replaces it, whole
    assert _frames(gif) == 3 and sorted(tmp_path.iterdir()) == [gif]


def test_default_fps_is_held_to_the_range(tmp_path, monkeypatch):
    """Without --fps the video plays at the env's render_fps (4 x frames per stroke), at most
    100 fps: 26 frames per stroke would be 104 fps, which a GIF cannot store."""
    from microconveyor_env.cli import video
    from microconveyor_env.envs import env_config
    from microconveyor_env.envs.core import video as env_video

    def fake_write(frames, path, fps):  # no encoding: only the rate asked for matters
        path.write_bytes(b"GIF8")
        return path

    monkeypatch.setattr(env_video, "write_video", fake_write)
    p = argparse.ArgumentParser()
    video.video_args(p)
    args = p.parse_args(["--out", str(tmp_path / "v.gif"), "--frames-per-stroke", "26"])
    args.out = tmp_path / "v.gif"
    cfg = env_config("MicroConveyor-v1", n_actuators=1)
    act, _ = video.schedule_actor(argparse.Namespace(freq=None, stroke=None, delay=None), cfg)
    assert video.make_video(args, cfg, act)["fps"] == 100.0
