"""./ws demo: a shipped trained policy plays one episode into a video; evaluate.py's JSON says how it did."""
import json
import os
import subprocess

import pytest

from workspace_tools.paths import REPO

REFUSE_CONTROLLER = REPO / "test" / "programs" / "refuse_controller"  # its sitecustomize.py: the controller raises


def demo(*args, cwd, env=None):
    return subprocess.run([str(REPO / "ws"), "demo", *args], cwd=cwd, capture_output=True, text=True, timeout=600,
                          env=env)


def refusing_controller(log):
    """The environment of a process in which any call into hopper_training.controller raises (each controller
    module that is imported writes one line to `log`)."""
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(REFUSE_CONTROLLER), os.environ.get("PYTHONPATH", "")]),
            "REFUSED_CONTROLLER_LOG": str(log)}


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


@pytest.mark.parametrize("policy, speed", [("end_to_end", None), ("end_to_end_forward", 0.35),
                                           ("end_to_end_scratch", None)])
def test_an_end_to_end_student_hops_10_s_with_the_controller_refused(tmp_path, policy, speed):
    """Issue 39: the shipped end-to-end policies play alone. Any call into hopper_training.controller raises in the
    demo's processes; the policy stays up the whole 10 s and hops at least 20 times (the forward one at 0.35 m/s
    or more along +x, for 0.4 commanded to its teacher). end_to_end_scratch was trained from scratch with the
    attitude assist, which the demo does not apply."""
    log = tmp_path / "refused.log"
    result = demo("hopper", f"policy:={policy}", "out.mp4", cwd=tmp_path, env=refusing_controller(log))
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert report["task"] == "MonopedEndToEnd-v0" and report["episodes"] == 1 and report["horizon_s"] == 10.0
    assert report["greedy"]["upright_whole_horizon_rate"] == 1.0 and report["greedy"]["mean_time_upright_s"] == 10.0
    assert report["greedy"]["mean_hops"] >= 20, report
    assert speed is None or report["greedy"]["mean_forward_speed"] >= speed, report
    assert (tmp_path / "out.mp4").stat().st_size > 0
    # the hook ran: evaluate.py imported the controller (its scripted policies name it), every call of it refused
    refused = {line.split()[1]: int(line.split()[2]) for line in log.read_text().splitlines()}
    assert refused.get("hopper_training.controller.core", 0) > 10 and "hopper_training.controller.policy" in refused


def test_the_refusing_hook_really_refuses_the_controller(tmp_path):
    """The hook above is honest: the controller itself, evaluated under it, fails at its first call."""
    result = subprocess.run([str(REPO / "ws"), "exec", "rosrun", "hopper_training", "evaluate.py", "--policy",
                             "controller", "--task", "end_to_end", "--episodes", "1", "--horizon-s", "0.1"],
                            cwd=tmp_path, capture_output=True, text=True, timeout=300,
                            env=refusing_controller(tmp_path / "refused.log"))
    assert result.returncode != 0
    assert "ControllerRefused: hopper_training.controller.policy.five_ms_controller was called" \
        in result.stderr, result.stderr[-2000:]


def test_an_unknown_policy_gets_one_line_naming_the_shipped_ones(tmp_path):
    result = demo("hopper", "policy:=nope", cwd=tmp_path)
    assert result.returncode != 0 and "no shipped policy 'nope' for hopper (known: demo, end_to_end, " \
        "end_to_end_forward, end_to_end_scratch, hop_in_place_push075, residual_forward_sac, residual_in_place_sac)" \
        in result.stderr, result.stderr
    assert not list(tmp_path.iterdir())


def test_an_unknown_robot_gets_one_line(tmp_path):
    result = demo("drone", cwd=tmp_path)
    assert result.returncode != 0 and "unknown robot 'drone' (known: cube, hopper)" in result.stderr
    assert not list(tmp_path.iterdir())
