"""Agent rllib_ppo for real: RLlib's PPO with its env runners on Ray (no mock), the cube on the direct backend. On a
Ray it starts itself on this machine: a short run writes every results file (episodes.csv with every episode once,
runners.csv naming each episode's runner), resumes from its weights-only checkpoint, and evaluate.py plays it
without Ray or torch; on a two-node loopback cluster (workspace_tools.ray_cluster) of 1 + 2 CPUs, three runners
(more than this machine's two cores) run on both nodes and every update has a fragment of each; a runner's node
killed mid-run, RLlib restarts its runner on the other node and the run completes with every episode once. Each run
is a driver process of its own, marked, so that no process of it may be left."""
import csv
import hashlib
import json
import os
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest

from moving_cube_training import TASKS as CUBE_TASKS
from robot_rl import TrainedRun, evaluate
from workspace_tools.launch_reaper import processes_with
from workspace_tools.ray_cluster import LoopbackCluster, process_name
from workspace_tools.ship import ship_run

pytestmark = [pytest.mark.ray, pytest.mark.deep]  # RLlib (requirements-distributed.txt) on torch

MARK = "ROBOT_RL_RLLIB_TEST_RUN"
RUN_TIMEOUT = 400  # s for a driver: Ray's start, RLlib's build (20-40 s on a busy 2-core machine), a few updates

DRIVER = """
import json, sys
from pathlib import Path
from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from robot_rl import DEEP_CHECKPOINT, RunDirectory, TrainingHooks, find_agent
root, nepisodes, resume, cluster = Path(sys.argv[1]), int(sys.argv[2]), sys.argv[3] == "resume", sys.argv[4]
n = int(sys.argv[5])
agent = find_agent("rllib_ppo")
params = ONE_DISK_WALK.default_params().with_changes("test", nepisodes=nepisodes)
run = RunDirectory.latest(root, "moving_cube-rllib_ppo", DEEP_CHECKPOINT) if resume else \\
    RunDirectory.create(root, "moving_cube-rllib_ppo", params.to_mapping(), ONE_DISK_WALK.metric_names,
                        checkpoint_name=DEEP_CHECKPOINT)
agent_params = agent.load_params().with_changes("test", rollout_fragment_length=32, batch_size=32, n_epochs=2)
envs = agent.make_vector_env(ONE_DISK_WALK, n, backend="direct", seed=params.seed, params=params, ros_timeout=10.0,
                             cluster=cluster or None)
try:
    lines = []
    trainer = agent.make_trainer(envs, ONE_DISK_WALK, params, run, TrainingHooks(log=lines.append, checkpoint_every=2),
                                 resume=resume, agent_params=agent_params)
    import ray
    driver_node = ray.get_runtime_context().get_node_id()
    summary = trainer.train()
finally:
    envs.close()
print(json.dumps({"run": str(run.path), "summary": summary, "lines": lines, "driver_node": driver_node}))
"""


def drive(tmp_path, nepisodes, resume=False, cluster="", env=None, meanwhile=None, envs=2):
    """One driver process (marked) of `envs` runners; `meanwhile()` runs while it trains; returns its JSON and
    asserts that nothing of it is left."""
    mark = uuid.uuid4().hex
    environment = {**os.environ, **(env or {}), MARK: mark}
    environment.pop("ROBOT_RL_CLUSTER_DIR", None)  # the test's cluster's token, not the workspace's
    with subprocess.Popen([sys.executable, "-c", DRIVER, str(tmp_path / "results"), str(nepisodes),
                           "resume" if resume else "new", cluster, str(envs)], env=environment, stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, text=True) as driver:
        try:
            if meanwhile is not None:
                meanwhile()
            stdout, stderr = driver.communicate(timeout=RUN_TIMEOUT)
        finally:
            if driver.poll() is None:
                driver.kill()
    done = subprocess.CompletedProcess(driver.args, driver.returncode, stdout, stderr)
    assert done.returncode == 0, done.stderr[-3000:]
    left = processes_with(MARK, mark)
    assert left == [], f"processes of the run left: {[process_name(p) for p in left]}"
    return json.loads(done.stdout.strip().splitlines()[-1])


def runners(run):
    with open(run / "runners.csv") as f:
        return list(csv.DictReader(f))


def test_a_short_run_writes_every_results_file_resumes_and_evaluates(tmp_path):
    first = drive(tmp_path, 6)
    run = Path(first["run"])
    for name in ("episodes.csv", "runners.csv", "params.yaml", "learning_curve.png", "summary.json", "agent.json",
                 "rllib_module.npz"):
        assert (run / name).is_file(), name
    assert not list(run.glob("*.partial*")) and not list(run.glob("*.pkl")), "weights only, whole"
    summary, checkpoint = first["summary"], json.loads((run / "agent.json").read_text())
    assert summary["completed"] and summary["episodes"] == 6 and summary["agent"] == "rllib_ppo"
    assert summary["env_steps"] == 64 * summary["updates"], "one 32-step fragment of each runner per update"
    assert checkpoint["weights_sha256"] == hashlib.sha256((run / "rllib_module.npz").read_bytes()).hexdigest()
    assert (checkpoint["episode"], checkpoint["envs"]) == (6, 2)
    rows = runners(run)
    assert [int(r["episode"]) for r in rows] == list(range(1, 7))
    assert {r["runner"] for r in rows} == {"1", "2"}, "both runners' episodes"
    assert sum(line.startswith("EP: ") for line in first["lines"]) == 6
    assert sum(line.startswith("env runner ") for line in first["lines"]) == 2

    second = drive(tmp_path, 10, resume=True)
    assert second["lines"][2].startswith(f"Resuming {run} after episode 6 ({summary['env_steps']} env steps)")
    with open(run / "episodes.csv") as f:
        assert [int(r["episode"]) for r in csv.DictReader(f)] == list(range(1, 11)), "every episode once"
    assert [int(r["episode"]) for r in runners(run)] == list(range(1, 11))
    assert second["summary"]["completed"] and second["summary"]["env_steps"] > summary["env_steps"]
    assert second["summary"]["updates"] > summary["updates"], "the counters went on"

    before = set(sys.modules)
    reports = [evaluate(TrainedRun(run, list(CUBE_TASKS)), episodes=2, horizon_s=0.6,
                        backend="direct", seed=3) for _ in range(2)]
    assert reports[0] == reports[1], "a deterministic policy on the direct backend repeats"
    assert set(reports[0]["greedy"]) == {"mean_return", "mean_y_distance", "success_rate"}
    assert not {"ray", "torch"} & (set(sys.modules) - before), "played in numpy: neither Ray nor torch loaded"
    shipped = tmp_path / "policies" / "demo"
    assert "rllib_module.npz" in ship_run(run, shipped, list(CUBE_TASKS))
    assert evaluate(TrainedRun(shipped, list(CUBE_TASKS)), episodes=2, horizon_s=0.6, backend="direct",
                    seed=3) == reports[0], "the shipped policy plays as the run"


def test_on_a_two_node_cluster_more_runners_than_cores_send_fragments_from_both_nodes(tmp_path):
    with LoopbackCluster(tmp_path / "cluster", nodes=2, head_cpus=1, cpus_per_node=2) as cluster:
        second = raylet_node_id(cluster, 1)
        # a cube episode takes about 10-20 env steps at first: 3 x 32 steps end fewer than 12 episodes, so those of
        # the first update are all written (the last update's are cut in runner order) and every runner has some
        result = drive(tmp_path, 12, cluster=cluster.address, env=cluster.driver_environment, envs=3)
        left = cluster.close()
    assert left == [], f"processes of the cluster left: {[process_name(p) for p in left]}"
    assert result["driver_node"] != second
    summary, rows = result["summary"], runners(Path(result["run"]))
    assert summary["env_steps"] == 3 * 32 * summary["updates"], "every update: a 32-step fragment of each runner"
    assert [int(r["episode"]) for r in rows] == list(range(1, 13))
    where = {(r["runner"], r["node_id"]) for r in rows}
    assert {runner for runner, _ in where} == {"1", "2", "3"}, "the three runners' episodes"
    assert {node for _, node in where} == {result["driver_node"], second}, \
        "one CPU on the head, two on the second node: runners' episodes from both"
    assert sum(node == second for _, node in where) == 2


def raylet_node_id(cluster, i):
    """Ray's id of the cluster's node i (its raylet's --node_id)."""
    leader = cluster.processes_started[i].pid
    for pid in cluster.processes():
        try:
            session = int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[3])
        except OSError:
            continue
        command = process_name(pid)
        if session == leader and "/raylet " in command:
            return command.split("--node_id=", 1)[1].split()[0]
    raise AssertionError(f"no raylet of node {i}")


def test_a_runner_s_node_lost_mid_run_the_run_completes_with_every_episode_once(tmp_path):
    with LoopbackCluster(tmp_path / "cluster", nodes=3, head_cpus=0, cpus_per_node=2) as cluster:
        nodes = {raylet_node_id(cluster, i): i for i in (1, 2)}
        results = tmp_path / "results" / "moving_cube-rllib_ppo"
        killed = []

        def kill_a_runner_s_node():
            deadline = time.monotonic() + RUN_TIMEOUT
            while time.monotonic() < deadline:  # until the first episode is written: the runners are up
                written = [folder / "runners.csv" for folder in results.glob("2*")] if results.is_dir() else []
                rows = runners(written[0].parent) if written and written[0].is_file() else []
                if rows:
                    killed.append(nodes[rows[0]["node_id"]])
                    cluster.kill_node(killed[0])
                    return
                time.sleep(0.05)
            raise AssertionError(f"no episode written within {RUN_TIMEOUT} s")
        result = drive(tmp_path, 16, cluster=cluster.address, env=cluster.driver_environment,
                       meanwhile=kill_a_runner_s_node)
        left = cluster.close()
    assert left == [], f"processes of the cluster left: {[process_name(p) for p in left]}"
    assert result["summary"]["completed"] and result["summary"]["episodes"] == 16
    run = Path(result["run"])
    with open(run / "episodes.csv") as f:
        assert [int(r["episode"]) for r in csv.DictReader(f)] == list(range(1, 17)), "every episode once"
    rows = runners(run)
    assert [int(r["episode"]) for r in rows] == list(range(1, 17))
    lost = [node for node, i in nodes.items() if i == killed[0]][0]
    assert any(r["node_id"] != lost for r in rows[1:]), "episodes after the loss came from the other node"
