"""./ws demo: a shipped trained policy plays one episode into a video; evaluate.py's JSON says how it did."""
import json
import subprocess

import pytest

from workspace_tools.paths import REPO


def demo(*args, cwd):
    return subprocess.run([str(REPO / "ws"), "demo", *args], cwd=cwd, capture_output=True, text=True, timeout=600)


@pytest.mark.parametrize(("args", "expected"), [
    (["cube"], {"success_rate": 1.0}),
    (["hopper"], {"upright_whole_horizon_rate": 1.0}),
    (["hopper", "policy:=residual_forward_sac"], {"upright_whole_horizon_rate": 1.0, "mean_forward_speed": 0.3}),
], ids=["cube", "hopper", "hopper-residual_forward_sac"])
def test_the_shipped_policy_plays_into_a_video_and_does_its_task(tmp_path, args, expected):
    result = demo(*args, "out.mp4", cwd=tmp_path)  # a relative path is the caller's folder's
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert report["episodes"] == 1, report
    for metric, least in expected.items():  # rates are 1.0 when met; the speed at least its target
        assert report["greedy"][metric] >= least, (metric, report)
    assert report["video"]["path"] == str(tmp_path / "out.mp4") and report["video"]["frames"] > 0
    assert (tmp_path / "out.mp4").stat().st_size > 0


def test_an_unknown_policy_gets_one_line_naming_the_shipped_ones(tmp_path):
    result = demo("hopper", "policy:=nope", cwd=tmp_path)
    assert result.returncode != 0 and "no shipped policy 'nope' for hopper (known: demo, residual_forward_sac, " \
        "residual_in_place_sac)" in result.stderr, result.stderr
    assert not list(tmp_path.iterdir())


def test_an_unknown_robot_gets_one_line(tmp_path):
    result = demo("drone", cwd=tmp_path)
    assert result.returncode != 0 and "unknown robot 'drone' (known: cube, hopper)" in result.stderr
    assert not list(tmp_path.iterdir())
