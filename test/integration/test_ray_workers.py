"""Env workers as Ray actors on a real two-node Ray cluster on this machine (workspace_tools.ray_cluster): a
tabular run with its envs on both nodes equals the same run over local workers; the actors step as pipe
workers do; ROS stays on loopback; a tabular run goes on when a node is lost (its actor restarted on the
other node), with no episode lost or repeated; without a restart a lost node stops the run naming the env;
nothing outlives a run, a closed env or a lost node, and the cluster leaves no process behind."""
import csv
import json
import os
import select
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from robot_rl import RunDirectory, TrainingHooks, WorkerError, find_agent, make_vector_env
from workspace_tools.paths import REPO
from workspace_tools.processes import RosMaster, launch_args
from workspace_tools.ray_cluster import LoopbackCluster, listening_sockets, process_name

from test_vector_ros import alive, short_params, wait_gone, write_config  # isort: skip  # this folder's

pytestmark = pytest.mark.ray  # needs Ray (requirements-distributed.txt)


RAY_WORKER_PORTS = range(10002, 20000)  # Ray's default --min/--max-worker-port: each Ray worker's own server
TIMING_COLUMNS = {"wall_time"}  # episodes.csv's columns that differ between two equal runs


def start_cluster(folder):
    return LoopbackCluster(folder, nodes=2, cpus_per_node=1)


def end_cluster(cluster):
    left = cluster.close()
    assert left == [], f"processes of the cluster left after its nodes ended: {[process_name(p) for p in left]}"


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """Two Ray nodes of one CPU each: two actors of one CPU each land one on each node."""
    nodes = start_cluster(tmp_path_factory.mktemp("cluster"))
    try:
        yield nodes
    finally:
        end_cluster(nodes)


def episodes(run):
    with open(run / "episodes.csv") as file:
        return [{k: v for k, v in row.items() if k not in TIMING_COLUMNS} for row in csv.DictReader(file)]


def checkpoint(run):
    """qtable.json without its clocks (when it was written, the run's wall time)."""
    saved = json.loads((run / "qtable.json").read_text())
    del saved["written_at"], saved["state"]["wall_time"]
    return saved


def train(tmp_path, name, state_dir=None, **args):
    master = RosMaster(tmp_path / f"ros-{name}", cwd=REPO)
    if state_dir is not None:  # the cluster's token
        master.env["ROBOT_RL_CLUSTER_DIR"] = str(state_dir)
    try:
        result = master.run(["rosrun", "workspace_tools", "roslaunch_checked.py", "moving_cube_training", "main.launch",
                             *launch_args(results_dir=tmp_path / "results", config=write_config(
                                 tmp_path / "c.yaml", nsteps=15), envs=2, nepisodes=6, video="false", run=name,
                                 **args)], timeout=600)
        (tmp_path / f"{name}.log").write_text(result.stdout + result.stderr)
        assert result.returncode == 0, (result.stdout + result.stderr)[-4000:]
        assert master.leftovers() == [], "every node of the launch is gone"
    finally:
        master.close()
    return result.stdout + result.stderr, tmp_path / "results" / "moving_cube" / name


def test_a_tabular_run_with_envs_on_both_nodes_equals_the_local_two_env_run(tmp_path, cluster):
    output, over_ray = train(tmp_path, "ray", cluster.folder, cluster=cluster.address)
    nodes = [line.split(" on node ")[1].split(")")[0] for line in output.splitlines() if "a Ray actor on node" in line]
    assert len(nodes) == 2 and len(set(nodes)) == 2, f"one actor on each node: {nodes}"
    _, local = train(tmp_path, "local")
    assert episodes(over_ray) == episodes(local) and len(episodes(local)) == 6
    assert checkpoint(over_ray) == checkpoint(local) and checkpoint(local)["episode"] == 6
    assert json.loads((over_ray / "summary.json").read_text())["completed"]


def test_actors_step_as_pipe_workers_on_two_nodes_with_ros_on_loopback(tmp_path, cluster):
    actions = [[0, 1], [3, 4], [0, 0], [2, 1], [1, 3], [0, 0], [4, 4], [1, 0]]

    def trajectory(env):
        observations = [env.reset(seed=9)[0]]
        observations += [env.step(action)[0] for action in actions]
        return np.array(observations)

    local = make_vector_env(ONE_DISK_WALK, 2, backend="ros", seed=9, params=short_params(), log_dir=tmp_path)
    try:
        expected = trajectory(local)
    finally:
        local.close()
    cluster.connect()
    try:
        env = make_vector_env(ONE_DISK_WALK, 2, backend="ros", seed=9, params=short_params(), cluster=cluster.address)
    except BaseException:
        cluster.disconnect()
        raise
    try:
        info = env.workers.worker_info
        assert len({worker["node_id"] for worker in info}) == 2, "one actor on each node"
        np.testing.assert_array_equal(trajectory(env), expected)
        actors = [worker["pid"] for worker in info]
        ros = [pid for worker in info for pid in worker["children"]]  # each actor's master and sim node
        assert set(actors + ros) <= set(cluster.processes()), "the actors are the cluster's processes"
        sockets = listening_sockets(actors + ros)
        for pid in ros:
            assert sockets[pid] and all(host == "127.0.0.1" for host, _ in sockets[pid]), (process_name(pid), sockets)
        for pid in actors:  # the actor's rospy node (XML-RPC, TCPROS) on loopback; its Ray worker's server is Ray's
            rospy_sockets = [(host, port) for host, port in sockets[pid] if port not in RAY_WORKER_PORTS]
            assert rospy_sockets and all(host == "127.0.0.1" for host, _ in rospy_sockets), sockets[pid]
    finally:
        env.close()
        cluster.disconnect()
    wait_gone(actors + ros)


def test_a_lost_node_stops_the_run_with_its_env_named_and_leaves_nothing(tmp_path):
    nodes = start_cluster(tmp_path / "cluster")
    try:
        nodes.connect()
        env = make_vector_env(ONE_DISK_WALK, 2, backend="ros", seed=0, params=short_params(), ros_timeout=5.0,
                              cluster=nodes.address, max_restarts=0)
        try:
            env.reset(seed=0)
            env.step([1, 1])
            second = nodes.processes_started[1].pid
            lost = next(i for i, worker in enumerate(env.workers.worker_info) if _on_node_of(worker["pid"], second))
            pids = [env.workers.worker_info[lost]["pid"], *env.workers.worker_info[lost]["children"]]
            nodes.kill_node(1, machine=False)  # its raylet crashed: its workers end once they find it gone
            deadline = time.monotonic() + 60.0
            with pytest.raises(WorkerError, match=rf"worker {lost} \(ray, on node .*\) was lost"):
                while time.monotonic() < deadline:
                    env.step([1, 1])
            wait_gone(pids, timeout=30.0)  # the lost node's actor, and its master and sim node (their death signal)
        finally:
            env.close()
    finally:
        end_cluster(nodes)


def test_a_tabular_run_goes_on_when_a_node_is_lost_and_loses_or_repeats_no_episode(tmp_path):
    """The second node killed mid-run: its actor is restarted on the head (2 CPUs), its episode under way starts
    anew, and the run ends with every episode once."""
    nodes = LoopbackCluster(tmp_path / "cluster", nodes=2, cpus_per_node=1, head_cpus=2)
    try:
        nodes.connect()
        params = ONE_DISK_WALK.default_params().with_changes("test", nsteps=15, nepisodes=30)
        env = make_vector_env(ONE_DISK_WALK, 2, backend="ros", seed=0, params=params, ros_timeout=5.0,
                              cluster=nodes.address)
        second = nodes.processes_started[1].pid
        lost = next(i for i, worker in enumerate(env.workers.worker_info) if _on_node_of(worker["pid"], second))
        pids = [env.workers.worker_info[lost]["pid"], *env.workers.worker_info[lost]["children"]]
        first_node = env.workers.worker_info[lost]["node_id"]
        steps, log = [0], []

        def on_step(*_):
            steps[0] += 1
            if steps[0] == 100:
                nodes.kill_node(1)
        try:
            run = RunDirectory.create(tmp_path / "results", "moving_cube", params.to_mapping(),
                                      ONE_DISK_WALK.metric_names, "lost")
            hooks = TrainingHooks(log=log.append, on_step=on_step)
            summary = find_agent("qlearn").make_trainer(env, ONE_DISK_WALK, params, run, hooks).train()
            moved = env.workers.worker_info[lost]["node_id"]
        finally:
            env.close()
        wait_gone(pids, timeout=30.0)
    finally:
        end_cluster(nodes)
    assert summary["completed"] and summary["episodes"] == 30, log[-5:]
    assert [int(row["episode"]) for row in episodes(run.path)] == list(range(1, 31))
    assert any(f"env {lost + 1}/2: worker {lost} (ray" in line and "starts anew" in line for line in log), log
    assert moved != first_node, "the lost actor runs on the other node now"


DRIVER = """
import json, sys, time
from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from robot_rl import make_vector_env
params = ONE_DISK_WALK.default_params().with_changes("test", nsteps=6)
env = make_vector_env(ONE_DISK_WALK, 2, backend="ros", seed=0, params=params, cluster=sys.argv[1])
env.reset(seed=0)
print(json.dumps([pid for worker in env.workers.worker_info for pid in (worker["pid"], *worker["children"])]))
sys.stdout.flush()
time.sleep(600)
"""


def test_a_killed_driver_takes_its_actors_and_their_masters_and_sims_with_it(tmp_path, cluster):
    env = {**os.environ, **cluster.driver_environment, "ROBOT_RL_CLUSTER_DIR": str(cluster.folder)}
    driver = subprocess.Popen([sys.executable, "-c", DRIVER, cluster.address], stdout=subprocess.PIPE, text=True,
                              env=env)
    try:
        ready, _, _ = select.select([driver.stdout], [], [], 120.0)
        assert ready, "the driver made no env within 120 s"
        pids = json.loads(driver.stdout.readline())
        assert len(pids) == 6 and all(alive(pid) for pid in pids), "2 actors, each with a master and a sim node"
    finally:
        driver.kill()
        driver.wait()
    wait_gone(pids, timeout=30.0)


def _on_node_of(pid, node_pid):
    """Whether `pid` descends from the node whose `ray start` is `node_pid` (its raylet started it)."""
    while pid > 1:
        if pid == node_pid:
            return True
        try:
            pid = int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])
        except OSError:
            return False
    return False


def test_the_cluster_ends_every_process_by_pid(tmp_path):
    nodes = start_cluster(tmp_path / "cluster")
    try:
        pids = nodes.processes()
        assert len([pid for pid in pids if "raylet" in process_name(pid)]) == 2, "two nodes, a raylet each"
        starts = [process.pid for process in nodes.processes_started]
    finally:
        end_cluster(nodes)
    assert not any(alive(pid) for pid in starts + pids)
    assert not any(Path(folder).exists() for folder in nodes.temp_dirs), "the nodes' temp folders are removed"

