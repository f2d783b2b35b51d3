"""A sim node killed and started again under a training run over ROS, with the sim in a launch of its own (as
the tutorials run Gazebo beside the training, or a launch file with respawn="true" would): the run stops with
one line saying whether the sim is gone or was restarted (a restarted sim starts over: time 0, the robot at
its spawn pose), the run folder stays whole, and resume:=true continues it on the new sim.
docs/reference/faults.md lists these cases."""
from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import xmlrpc.client
from pathlib import Path
from typing import Any

import pytest
import rosgraph
import yaml

from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from workspace_tools.paths import PROGRAMS
from workspace_tools.processes import RosMaster, wait_for
from workspace_tools.training_launch import write_cube_training_launch

TRAIN = ["rosrun", "workspace_tools", "roslaunch_checked.py"]  # what ./ws run starts
SIM = ["roslaunch", "pybullet_sim", "cube_sim.launch", "robot_state_publisher:=false"]
STEP_SERVICE = "/pybullet_sim/step_packed"


def training_launch(tmp_path: Path) -> Path:
    """The cube's training (train.launch and the training node) with a sim launch that starts nothing: the
    sim runs in a launch of its own. A long run: the angle limits are out of reach, every episode lasts 50 steps."""
    config = tmp_path / "config.yaml"
    document = yaml.safe_load(ONE_DISK_WALK.config_path.read_text())
    document["moving_cube"].update(nepisodes=400, nsteps=50, max_pitch_angle=10.0, max_yaw_angle=10.0)
    config.write_text(yaml.safe_dump(document))
    no_sim = tmp_path / "no_sim.launch"
    no_sim.write_text('<launch><arg name="paused"/><arg name="seed"/><arg name="gui"/>'
                      '<arg name="robot_state_publisher"/><arg name="rviz"/></launch>')
    return write_cube_training_launch(tmp_path / "training.launch", no_sim, config, tmp_path / "results")


def sim_address(master: RosMaster) -> str | None:
    """Where the sim node serves its lockstep step now (None: no sim)."""
    try:
        return str(master.params.lookupService(STEP_SERVICE))
    except rosgraph.MasterError:
        return None


def start_sim(master: RosMaster, log: Path, previous: str | None = None) -> subprocess.Popen:
    """The cube's sim launch, once its step service is up (at another address than `previous`)."""
    with open(log, "w") as out:
        sim = master.start(SIM, stdout=out, stderr=subprocess.STDOUT)
    wait_for(lambda: sim_address(master) not in (None, previous), 60, f"the sim's {STEP_SERVICE}")
    return sim


def node_pid(master: RosMaster, name: str) -> int:
    """A node's pid, from its own XML-RPC server (the master knows where it is)."""
    answer: Any = xmlrpc.client.ServerProxy(master.params.lookupNode(name)).getPid("/test")  # (code, status, pid)
    return int(answer[2])


def episodes(results: Path) -> list[int]:
    lines = (results / "moving_cube" / "latest" / "episodes.csv").read_text().split("\n")[1:-1]
    return [int(line.split(",")[0]) for line in lines]


@pytest.mark.parametrize("when, expected", [
    ("after_the_run_noticed", "the sim node is gone (nothing serves /pybullet_sim/step_packed any more"),
    ("before_the_next_call", "the sim node was restarted (it serves /pybullet_sim/step_packed at rosrpc://"),
], ids=["gone", "restarted"])
def test_a_sim_restarted_mid_run_stops_it_with_one_line_and_resume_continues(master, tmp_path, when, expected):
    """SIGKILL of the sim node by its pid, then the same sim launch again. "gone": the run's next step finds
    no sim and stops before the new one is up; "restarted": the training node is held (SIGSTOP) until the new
    sim serves, so that its next step meets a restarted sim."""
    sim = start_sim(master, tmp_path / "sim.log")
    first_address = sim_address(master)
    master.params.setParam("/movingcube_gym/timeout", 60.0)  # the held training node's step must not time out
    launch, log = training_launch(tmp_path), tmp_path / "run.log"
    with open(log, "w") as out:
        training = master.start([*TRAIN, str(launch)], stdout=out, stderr=subprocess.STDOUT)
    wait_for(lambda: "EP: 12 " in log.read_text(), 120, "episode 12")
    trainer = node_pid(master, "/movingcube_gym")
    if when == "before_the_next_call":
        os.kill(trainer, signal.SIGSTOP)
    try:
        os.kill(node_pid(master, "/pybullet_sim"), signal.SIGKILL)
        sim.wait(30)  # the sim is required in its launch: the launch ends with it
        if when == "after_the_run_noticed":
            assert training.wait(60) == 1, log.read_text()[-3000:]
        sim = start_sim(master, tmp_path / "sim2.log", previous=first_address)
    finally:
        if when == "before_the_next_call":
            os.kill(trainer, signal.SIGCONT)
    assert training.wait(60) == 1, log.read_text()[-3000:]

    output = log.read_text()
    lines = [line for line in output.splitlines() if "[FATAL]" in line]
    assert len(lines) == 1 and "Traceback" not in output, output[-3000:]
    assert expected in lines[0] and "continue with resume:=true" in lines[0], lines[0]
    results = tmp_path / "results"
    summary = json.loads((results / "moving_cube" / "latest" / "summary.json").read_text())
    saved = json.loads((results / "moving_cube" / "latest" / "qtable.json").read_text())["episode"]
    assert summary["completed"] is False and summary["episodes"] == saved >= 12
    assert int(re.search(r"Episodes up to episode (\d+)", lines[0]).group(1)) == saved
    assert episodes(results) == list(range(1, saved + 1))

    resumed = master.run([*TRAIN, str(launch), "resume:=true", f"nepisodes:={saved + 3}"], timeout=180)
    assert resumed.returncode == 0, (resumed.stdout + resumed.stderr)[-3000:]
    assert episodes(results) == list(range(1, saved + 4)), "the run goes on on the new sim, no episode lost"
    sim.send_signal(signal.SIGINT)
    assert sim.wait(30) == 0


@pytest.mark.parametrize("restart", [True, False], ids=["restarted", "gone"])
def test_every_call_after_the_sim_is_lost_gives_the_clear_line(master, tmp_path, restart):
    """An env over ROS (a user's script) whose sim node was killed, and started again or not, keeps answering every
    step and reset with the one clear line (before: the second step gave rospy's TransportTerminated and the third
    an AttributeError)."""
    sim = start_sim(master, tmp_path / "sim.log")
    first_address = sim_address(master)
    client = master.start([sys.executable, str(PROGRAMS / "lost_sim_client.py")], stdin=subprocess.PIPE,
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert client.stdout.readline() == "ready\n", client.stderr.read()[-3000:]  # bounded: it prints or ends
        os.kill(node_pid(master, "/pybullet_sim"), signal.SIGKILL)
        sim.wait(30)
        if restart:
            sim = start_sim(master, tmp_path / "sim2.log", previous=first_address)
        client.stdin.write("go\n")
        client.stdin.flush()
        output, errors = client.communicate(timeout=120)
    finally:
        if client.poll() is None:
            client.kill()
        if sim.poll() is None:
            sim.send_signal(signal.SIGINT)
            sim.wait(30)
    lines = output.splitlines()
    assert client.returncode == 0 and len(lines) == 4, output + errors[-3000:]
    expected = "the sim node was restarted (it serves" if restart else "the sim node is gone (nothing serves"
    for line in lines:
        assert line.startswith("SimConnectionError: service ") and expected in line, lines
