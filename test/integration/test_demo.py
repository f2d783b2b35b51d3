"""./ws demo: a shipped trained policy plays one episode into a video; evaluate.py's JSON says how it did."""
import json
import subprocess

import pytest

from workspace_tools.paths import REPO


def demo(*args, cwd):
    return subprocess.run([str(REPO / "ws"), "demo", *args], cwd=cwd, capture_output=True, text=True, timeout=600)


@pytest.mark.parametrize(("robot", "metric", "expected"), [("cube", "success_rate", 1.0),
                                                            ("hopper", "upright_whole_horizon_rate", 1.0)])
def test_the_shipped_policy_plays_into_a_video_and_does_its_task(tmp_path, robot, metric, expected):
    result = demo(robot, "out.mp4", cwd=tmp_path)  # a relative path is the caller's folder's
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert report["episodes"] == 1 and report["greedy"][metric] == expected, report
    assert report["video"]["path"] == str(tmp_path / "out.mp4") and report["video"]["frames"] > 0
    assert (tmp_path / "out.mp4").stat().st_size > 0


def test_an_unknown_robot_gets_one_line(tmp_path):
    result = demo("drone", cwd=tmp_path)
    assert result.returncode != 0 and "unknown robot 'drone' (known: cube, hopper)" in result.stderr
    assert not list(tmp_path.iterdir())
