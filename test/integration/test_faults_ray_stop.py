"""SIGTERM (or SIGINT) while a Ray wait does not end (issue 42: every wait on Ray ended by SIGTERM within 10 s), on
a real one-node Ray cluster of this machine (workspace_tools.ray_cluster). A `cluster:=` training node waiting on an
actor that cannot start (a run of more envs than the cluster has CPUs: Ray never places the last one) or on one whose
process is frozen mid-run (SIGSTOP) ends within 10 s as a stopped run does (exit 130, its one line; mid-run a
checkpoint and summary.json marked interrupted), and no actor, master or sim node of the run is left. A sweep's
driver waiting in Ray Tune ends within 10 s as an interrupted sweep, and its trials' trainings end with it."""
import json
import os
import re
import signal
import subprocess
import sys
import time

import pytest
import yaml

from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from workspace_tools.paths import REPO
from workspace_tools.processes import RosMaster, alive, group_members, launch_args, wait_for
from workspace_tools.ray_cluster import LoopbackCluster, process_name

pytestmark = pytest.mark.ray  # needs Ray (requirements-distributed.txt)

STOP_BOUND = 10.0  # s from SIGTERM to the end (issue 42)
INTERRUPTED = 130
TRIALS_END = 30.0  # s for a stopped sweep's trials to end after its driver (Ray's notice, then the launch reapers')
RUN_PROCESSES = ("EnvActor", "rosmaster", "sim_node")  # an actor's Ray process, and its master and sim node


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """One Ray node of 2 CPUs: two actors of one CPU each fit, a third never does."""
    with LoopbackCluster(tmp_path_factory.mktemp("cluster"), nodes=1, cpus_per_node=2) as loopback:
        yield loopback


def run_processes(cluster):
    """The cluster's processes that belong to a run (its node's Ray daemons and idle workers aside)."""
    return [f"{pid}: {name[:150]}" for pid in cluster.processes()
            if any(part in (name := process_name(pid)) for part in RUN_PROCESSES)]


def start_training(master, cluster, tmp_path, log, envs, **changes):
    document = yaml.safe_load(ONE_DISK_WALK.config_path.read_text())
    document["moving_cube"].update({"nepisodes": 400, "nsteps": 50, "max_pitch_angle": 10.0, "max_yaw_angle": 10.0,
                                    **changes})  # angle limits out of reach: every episode lasts nsteps
    config = tmp_path / "config.yaml"
    config.write_text(yaml.safe_dump(document))
    master.env.update(cluster.driver_environment, ROBOT_RL_CLUSTER_DIR=str(cluster.folder))
    with open(log, "w") as out:
        return master.start(["rosrun", "workspace_tools", "roslaunch_checked.py", "moving_cube_training", "main.launch",
                             *launch_args(config=config, results_dir=tmp_path / "results", envs=envs, video="false",
                                          cluster=cluster.address)], stdout=out, stderr=subprocess.STDOUT)


def training_node(master):
    pids = [pid for pid in master.leftovers() if "start_training" in process_name(pid)]
    return pids[0] if len(pids) == 1 else None


def sigterm_ends_it_within_the_bound(master, launch, log):
    """SIGTERM to the training node (as roslaunch's shutdown sends it); the node must be gone within STOP_BOUND s
    and the launch must end with it (the node is required)."""
    node = training_node(master)
    assert node is not None, log.read_text()[-3000:]
    os.kill(node, signal.SIGTERM)
    sent = time.monotonic()
    while alive(node):
        if time.monotonic() - sent > STOP_BOUND:
            pytest.fail(f"the training node was still running {STOP_BOUND} s after SIGTERM:\n"
                        f"{log.read_text()[-3000:]}")
        time.sleep(0.05)
    assert launch.wait(60) == INTERRUPTED, log.read_text()[-3000:]
    return log.read_text()


def test_sigterm_while_an_actor_cannot_start_ends_the_run_within_10_s(cluster, tmp_path):
    """envs:=3 on 2 CPUs: two actors start their masters and sims, Ray never places the third, and the node waits
    for it (start_timeout, 60 s). SIGTERM ends that wait."""
    master = RosMaster(tmp_path / "ros", cwd=REPO)
    log = tmp_path / "run.log"
    try:
        launch = start_training(master, cluster, tmp_path, log, envs=3)
        wait_for(lambda: len([p for p in run_processes(cluster) if "sim_node" in p]) == 2, 120,
                 f"two actors' sim nodes (log {log})")
        output = sigterm_ends_it_within_the_bound(master, launch, log)
        assert "stopped before training started" in output and "Traceback" not in output, output[-3000:]
        wait_for(lambda: not run_processes(cluster), STOP_BOUND, "the end of every actor, master and sim of the run")
        assert master.leftovers() == [], [process_name(pid) for pid in master.leftovers()]
    finally:
        master.close()
    assert not (tmp_path / "results").exists() or not any((tmp_path / "results").rglob("summary.json"))


def test_sigterm_while_an_actor_is_frozen_mid_run_saves_and_ends_within_10_s(cluster, tmp_path):
    """envs:=2, one actor's process frozen (SIGSTOP) mid-run: the node waits for its reply (ros_timeout + 30 s).
    SIGTERM ends that wait; the run is saved as a stopped one and the frozen actor is killed with its master and
    sim node."""
    master = RosMaster(tmp_path / "ros", cwd=REPO)
    log = tmp_path / "run.log"
    frozen = None
    try:
        launch = start_training(master, cluster, tmp_path, log, envs=2)
        wait_for(lambda: "EP: 3 " in log.read_text(), 180, f"episode 3 (log {log})")
        actors = [int(p.split(":")[0]) for p in run_processes(cluster) if "EnvActor" in p]
        assert len(actors) == 2, run_processes(cluster)
        frozen = actors[0]
        os.kill(frozen, signal.SIGSTOP)
        output = sigterm_ends_it_within_the_bound(master, launch, log)
        line = [line for line in output.splitlines() if "training interrupted after episode" in line]
        assert len(line) == 1 and "Traceback" not in output, output[-3000:]
        saved = int(re.search(r"after episode (\d+):", line[0]).group(1))
        run = tmp_path / "results" / "moving_cube" / "latest"
        summary = json.loads((run / "summary.json").read_text())
        assert (summary["completed"], summary["stopped"], summary["episodes"]) == (False, "interrupted", saved)
        assert json.loads((run / "qtable.json").read_text())["episode"] == saved >= 3
        wait_for(lambda: not run_processes(cluster), STOP_BOUND, "the end of every actor, master and sim of the run")
        assert master.leftovers() == [], [process_name(pid) for pid in master.leftovers()]
    finally:
        if frozen is not None and alive(frozen):
            os.kill(frozen, signal.SIGKILL)
        master.close()


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_a_signal_to_a_sweep_driver_mid_trial_ends_it_within_10_s(cluster, tmp_path, signum):
    """A sweep of two trials, one on each CPU; SIGTERM (or Ctrl-C's SIGINT) to its driver once a trial has
    checkpointed: the driver ends within 10 s as an interrupted sweep (exit 130, its line naming resume:=true; Tune's
    own stop took 19 s for SIGINT, and SIGTERM ended it with exit 1 and no word), the trials' trainings end with it
    (as with a killed driver: each run keeps its last checkpoint, from which resume:=true goes on: test_sweep.py),
    and nothing of the sweep is left."""
    results, log = tmp_path / "results", tmp_path / "sweep.log"
    sweep = results / "moving_cube" / "stopped"
    env = {**os.environ, **cluster.driver_environment, "ROBOT_RL_CLUSTER_DIR": str(cluster.folder)}
    with open(log, "wb") as out:
        driver = subprocess.Popen(
            [sys.executable, "-m", "workspace_tools.sweep", "cube", "seeds:=0-1", "nepisodes:=400", "nsteps:=50",
             "name:=stopped", "eval_episodes:=1", f"results_dir:={results}", f"cluster:={cluster.address}"],
            env=env, cwd=REPO, stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        wait_for(lambda: any((sweep / f"seed={seed}" / "qtable.json").is_file() for seed in (0, 1)), 300,
                 f"a trial's first checkpoint (log {log})")
        # a run checkpoints every 10 episodes: these seeds had trained when the signal came (the other trial may
        # not have finished an episode yet, and then keeps the checkpoint its stop writes, at episode 0)
        trained = [seed for seed in (0, 1) if (sweep / f"seed={seed}" / "qtable.json").is_file()]
        driver.send_signal(signum)
        try:
            code = driver.wait(STOP_BOUND)
        except subprocess.TimeoutExpired:
            pytest.fail(f"the sweep's driver was still running {STOP_BOUND} s after {signum.name}:\n"
                        f"{log.read_text()[-3000:]}")
    finally:
        if driver.poll() is None:
            os.killpg(driver.pid, signal.SIGKILL)
            driver.wait(30)
    output = log.read_text()
    assert code == INTERRUPTED, output[-3000:]
    assert "interrupted with 2 trial(s) not done; continue with ./ws sweep cube name:=stopped resume:=true" in output, \
        output[-3000:]
    assert "Traceback" not in output, output[-3000:]
    def training_processes():
        return [f"{p}: {process_name(p)[:150]}" for p in cluster.processes() if any(
            name in process_name(p) for name in ("roslaunch", "rosmaster", "sim_node", "start_training"))]
    # The trials end once Ray has seen the driver go: their launch reapers SIGTERM them, and SIGKILL 5 s later.
    try:
        wait_for(lambda: not training_processes(), TRIALS_END, "the end of every training process of the sweep")
    except AssertionError as error:
        raise AssertionError(f"{error}: {training_processes()}") from None
    assert group_members(driver.pid) == [], [process_name(p) for p in group_members(driver.pid)]
    assert f"[sweep] stopped ({signal.Signals(signum).name})" in output, output[-3000:]
    checkpointed = [seed for seed in (0, 1) if (sweep / f"seed={seed}" / "qtable.json").is_file()]
    assert trained and set(trained) <= set(checkpointed), output[-3000:]
    for seed in checkpointed:  # each run keeps its checkpoint, whole, and is not called complete
        episode = json.loads((sweep / f"seed={seed}" / "qtable.json").read_text())["episode"]
        assert episode >= (1 if seed in trained else 0), (seed, episode)
        summary = sweep / f"seed={seed}" / "summary.json"
        assert not summary.exists() or json.loads(summary.read_text())["completed"] is False
