"""SIGTERM to a training node while it waits on the sim over ROS (issue 42: every wait on ROS ended by SIGTERM within
10 s): the sim node frozen (SIGSTOP) mid-step with a long `timeout:=` (60 s), so the node's step call waits for an
answer that does not come. SIGTERM ends that wait within 10 s as a stopped run does: exit 130, its one line, a
checkpoint and summary.json marked interrupted, and no process of the launch left."""
import json
import os
import re
import signal
import subprocess
import time
from pathlib import Path

import yaml

from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from workspace_tools.paths import REPO
from workspace_tools.processes import RosMaster, alive, launch_args, wait_for

STOP_BOUND = 10.0  # s from SIGTERM to the node's end (issue 42)
INTERRUPTED = 130


def command_of(pid):
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return ""


def test_sigterm_while_the_sim_is_frozen_mid_step_ends_the_run_within_10_s(tmp_path):
    document = yaml.safe_load(ONE_DISK_WALK.config_path.read_text())
    document["moving_cube"].update(nepisodes=400, nsteps=50, max_pitch_angle=10.0, max_yaw_angle=10.0)
    config = tmp_path / "config.yaml"
    config.write_text(yaml.safe_dump(document))
    master = RosMaster(tmp_path / "ros", cwd=REPO)
    log = tmp_path / "run.log"
    sim = None
    try:
        with open(log, "w") as out:
            launch = master.start(["rosrun", "workspace_tools", "roslaunch_checked.py", "moving_cube_training",
                                   "main.launch", *launch_args(config=config, results_dir=tmp_path / "results",
                                                               video="false", timeout=60)],
                                  stdout=out, stderr=subprocess.STDOUT)
        wait_for(lambda: "EP: 12 " in log.read_text(), 120, f"episode 12 (log {log})")
        pids = {name: [pid for pid in master.leftovers() if name in command_of(pid)]
                for name in ("sim_node", "start_training")}
        assert len(pids["sim_node"]) == 1 and len(pids["start_training"]) == 1, pids
        sim, node = pids["sim_node"][0], pids["start_training"][0]
        os.kill(sim, signal.SIGSTOP)  # the node's next step call waits for an answer (up to timeout:=60)
        os.kill(node, signal.SIGTERM)
        sent = time.monotonic()
        while alive(node):
            assert time.monotonic() - sent < STOP_BOUND, \
                f"the training node was still running {STOP_BOUND} s after SIGTERM:\n{log.read_text()[-3000:]}"
            time.sleep(0.05)
        os.kill(sim, signal.SIGCONT)  # roslaunch ends the rest of the launch (the node is required)
        assert launch.wait(60) == INTERRUPTED, log.read_text()[-3000:]
        output = log.read_text()
        lines = [line for line in output.splitlines() if "training interrupted after episode" in line]
        assert len(lines) == 1 and "Traceback" not in output, output[-3000:]
        saved = int(re.search(r"after episode (\d+):", lines[0]).group(1))
        run = tmp_path / "results" / "moving_cube" / "latest"
        summary = json.loads((run / "summary.json").read_text())
        assert (summary["completed"], summary["stopped"], summary["episodes"]) == (False, "interrupted", saved)
        assert json.loads((run / "qtable.json").read_text())["episode"] == saved >= 12
        assert master.leftovers() == [], [command_of(pid) for pid in master.leftovers()]
    finally:
        if sim is not None and alive(sim):
            os.kill(sim, signal.SIGCONT)
        master.close()
