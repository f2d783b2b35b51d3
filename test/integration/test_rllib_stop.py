"""SIGTERM to an agent rllib_ppo training node mid-update (issue 42: every wait on Ray ended by SIGTERM within 10 s),
through the cube's main.launch with backend:=direct and its own private Ray: the node ends within 10 s as a stopped
run (exit 130, one line; summary.json marked interrupted; the checkpoint of the last finished update, whose weights
load back), and no runner of it is left, nor a folder of it in /tmp. Before the fix ray.init had replaced the node's
SIGTERM handler with Ray's, which aborted the process (exit -6, no summary)."""
import json
import os
import re
import signal
import subprocess
import time
from pathlib import Path

import pytest

from robot_rl.agents.rllib.policy import WEIGHTS_DIGEST, WEIGHTS_FILE, load_weights
from workspace_tools.paths import REPO
from workspace_tools.processes import RosMaster, alive, launch_args, wait_for
from workspace_tools.ray_cluster import process_name

pytestmark = [pytest.mark.ray, pytest.mark.deep]  # RLlib (requirements-distributed.txt) on torch

STOP_BOUND = 10.0  # s from SIGTERM to the end (issue 42)
INTERRUPTED = 130


def test_sigterm_mid_update_ends_an_rllib_run_within_10_s_and_keeps_its_checkpoint(tmp_path):
    master = RosMaster(tmp_path / "ros", cwd=REPO)
    log, results = tmp_path / "run.log", tmp_path / "results"
    temp_folders = set(Path("/tmp").glob("rrl-ray-*")) | set(Path("/tmp").glob("robot_rl-rllib-runner*"))
    try:
        with open(log, "w") as out:  # 1024-step fragments: an update takes well over 10 s on these cores
            launch = master.start(["rosrun", "workspace_tools", "roslaunch_checked.py", "moving_cube_training",
                                   "main.launch", *launch_args(agent="rllib_ppo", backend="direct", envs=2,
                                                               nepisodes=5000, video="false", results_dir=results)],
                                  stdout=out, stderr=subprocess.STDOUT)
        wait_for(lambda: "progress: episode" in log.read_text(), 300, f"the run's first progress line (log {log})")
        runners = [int(pid) for pid in re.findall(r"env runner \d/2: pid (\d+)", log.read_text())]
        assert len(runners) == 2, log.read_text()[-3000:]
        nodes = [pid for pid in master.leftovers() if "start_training" in process_name(pid)]
        assert len(nodes) == 1, [process_name(pid) for pid in master.leftovers()]
        os.kill(nodes[0], signal.SIGTERM)
        sent = time.monotonic()
        wait_for(lambda: not alive(nodes[0]), STOP_BOUND, f"the training node's end after SIGTERM (log {log})")
        assert time.monotonic() - sent <= STOP_BOUND
        assert launch.wait(60) == INTERRUPTED, log.read_text()[-3000:]
        output = log.read_text()
        line = [line for line in output.splitlines() if "training interrupted after episode" in line]
        assert len(line) == 1 and "Traceback" not in output and "SIGTERM received" not in output, output[-3000:]
        saved = int(re.search(r"after episode (\d+):", line[0]).group(1))
        run = results / "moving_cube-rllib_ppo" / "latest"
        summary = json.loads((run / "summary.json").read_text())
        assert (summary["completed"], summary["stopped"], summary["episodes"]) == (False, "interrupted", saved)
        checkpoint = json.loads((run / "agent.json").read_text())
        assert checkpoint["episode"] == saved > 0
        assert load_weights(run / WEIGHTS_FILE, checkpoint[WEIGHTS_DIGEST], run / "agent.json")  # its sha256 holds
        wait_for(lambda: not any(alive(pid) for pid in runners), 30, "the end of both env runners")
        assert master.leftovers() == [], [process_name(pid) for pid in master.leftovers()]
        left = set(Path("/tmp").glob("rrl-ray-*")) | set(Path("/tmp").glob("robot_rl-rllib-runner*"))
        assert left == temp_folders, f"the run's Ray and runner folders are left: {sorted(left - temp_folders)}"
    finally:
        master.close()
