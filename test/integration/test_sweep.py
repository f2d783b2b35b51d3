"""`./ws sweep` (workspace_tools.sweep) on a real Ray cluster of two nodes on this machine
(workspace_tools.ray_cluster), each trial a real training launch on a master of its own: a 3-seed sweep writes
3 run folders and one table, each run the same as that seed's run alone; a DQN sweep trains each trial with
the task's own DQN file and the trial's values, for the step budget it gives; a sweep whose driver is killed
mid-run leaves no training process behind and, resumed, ends with every episode once, the checkpointed ones
as they were."""
import csv
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from workspace_tools.paths import REPO
from workspace_tools.processes import RosMaster, launch_args, wait_for
from workspace_tools.ray_cluster import LoopbackCluster

pytestmark = pytest.mark.ray  # needs Ray (requirements-distributed.txt)

SWEEP_TIMEOUT = 600.0
TRAINING_PROCESSES = ("roslaunch", "rosmaster", "sim_node", "start_training", "rosout")


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    with LoopbackCluster(tmp_path_factory.mktemp("cluster"), nodes=2, cpus_per_node=1) as loopback:
        yield loopback


def start_sweep(cluster: LoopbackCluster, results: Path, log: Path, *args: str) -> subprocess.Popen:
    env = {**os.environ, **cluster.driver_environment, "ROBOT_RL_CLUSTER_DIR": str(cluster.folder)}
    with open(log, "ab") as out:
        return subprocess.Popen([sys.executable, "-m", "workspace_tools.sweep", "cube", *args,
                                 f"results_dir:={results}", f"cluster:={cluster.address}"], env=env, cwd=REPO,
                                stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)


def finish(process: subprocess.Popen, log: Path) -> int:
    try:
        return process.wait(SWEEP_TIMEOUT)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        raise AssertionError(f"the sweep did not end within {SWEEP_TIMEOUT} s:\n{log.read_text()[-4000:]}") from None


def run_alone(tmp: Path, seed: int, **changes) -> Path:
    """The seed's run as ./ws run trains it (seed:=S, a config with `changes`); returns its folder."""
    document = yaml.safe_load(ONE_DISK_WALK.config_path.read_text())
    document["moving_cube"].update(changes)
    config = tmp / f"alone-{seed}.yaml"
    config.write_text(yaml.safe_dump(document))
    master = RosMaster(tmp / f"ros-alone-{seed}", cwd=REPO)
    try:
        result = master.run(["rosrun", "workspace_tools", "roslaunch_checked.py", "moving_cube_training", "main.launch",
                             *launch_args(config=config, results_dir=tmp / "alone", run=f"seed{seed}", seed=seed,
                                          video="false", quiet="true")], timeout=300)
    finally:
        master.close()
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-2000:]
    return tmp / "alone" / "moving_cube" / f"seed{seed}"


def episodes(run: Path) -> list:
    """episodes.csv without its wall-time column."""
    rows = list(csv.reader(run.joinpath("episodes.csv").read_text().splitlines()))
    wall = rows[0].index("wall_time")
    return [row[:wall] + row[wall + 1:] for row in rows]


def learned(run: Path) -> dict:
    checkpoint = json.loads(run.joinpath("qtable.json").read_text())
    return {"episode": checkpoint["episode"], "qlearn": checkpoint["qlearn"]}


def assert_same_run(trial: Path, alone: Path) -> None:
    assert episodes(trial) == episodes(alone)
    assert learned(trial) == learned(alone)


def training_processes(cluster: LoopbackCluster) -> list[str]:
    """The cluster's processes that belong to a training run (its nodes' Ray daemons aside)."""
    found = []
    for pid in cluster.processes():
        try:
            command = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if any(name in command for name in TRAINING_PROCESSES):
            found.append(f"{pid}: {command[:200]}")
    return found


def test_a_three_seed_sweep_writes_three_runs_each_as_the_seed_alone_and_one_table(cluster, tmp_path):
    results, log = tmp_path / "results", tmp_path / "sweep.log"
    code = finish(start_sweep(cluster, results, log, "seeds:=0-2", "nepisodes:=3", "nsteps:=50", "name:=three",
                              "eval_episodes:=2"), log)
    output = log.read_text()
    assert code == 0, output[-4000:]
    sweep = results / "moving_cube" / "three"
    trials = ["seed=0", "seed=1", "seed=2"]
    assert sorted(p.name for p in sweep.iterdir() if p.is_dir() and p.name.startswith("seed=")) == trials
    for name in trials:
        for file in ("params.yaml", "episodes.csv", "qtable.json", "learning_curve.png", "summary.json",
                     "evaluation.json"):
            assert (sweep / name / file).is_file(), f"{name}/{file} missing:\n{output[-3000:]}"
        evaluation = json.loads((sweep / name / "evaluation.json").read_text())
        assert evaluation["episodes"] == 2 and set(evaluation) >= {"greedy", "random"}
    assert sum(f"done: seed={s}:" in output for s in range(3)) == 3, output[-3000:]
    rows = list(csv.DictReader((sweep / "sweep.csv").read_text().splitlines()))
    assert [row["trial"] for row in rows] == trials and {row["episodes"] for row in rows} == {"3"}
    assert "greedy_success_rate" in rows[0] and "random_success_rate" in rows[0]
    markdown = (sweep / "sweep.md").read_text().splitlines()
    assert sum(line.startswith("| seed=") for line in markdown) == 3
    assert (sweep / "learning_curves.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for seed in range(3):
        assert_same_run(sweep / f"seed={seed}", run_alone(tmp_path, seed, nepisodes=3, nsteps=50))
    assert training_processes(cluster) == []


def test_a_deep_agent_sweep_sets_the_agent_s_params_and_step_budget_of_each_trial(cluster, tmp_path):
    results, log = tmp_path / "results", tmp_path / "sweep.log"
    code = finish(start_sweep(cluster, results, log, "agent:=dqn", "seeds:=0", "learning_rate:=1e-4,3e-4",
                              "learning_starts:=20", "max_steps:=60", "nsteps:=20", "name:=deep",
                              "eval_episodes:=1"), log)
    output = log.read_text()
    assert code == 0, output[-4000:]
    sweep = results / "moving_cube-dqn" / "deep"
    for name, rate in (("seed=0,learning_rate=0.0001", 1e-4), ("seed=0,learning_rate=0.0003", 3e-4)):
        summary = json.loads((sweep / name / "summary.json").read_text())
        checkpoint = json.loads((sweep / name / "agent.json").read_text())
        assert summary["completed"] and summary["env_steps"] == 60, "the step budget, not nepisodes, ended it"
        assert summary["agent_config"] == str(sweep / "configs" / f"{name}.agent.yaml")
        tuned = yaml.safe_load((REPO / "moving_cube_training/config/agents/one_disk_walk.dqn.yaml").read_text())
        assert checkpoint["agent_params"] == {"reward_scale": 1.0} | tuned | {"learning_rate": rate,
                                                                             "learning_starts": 20}, \
            "the task's own DQN file with the trial's values"
    assert training_processes(cluster) == []


def test_a_sweep_whose_driver_is_killed_resumes_with_every_episode_once(cluster, tmp_path):
    results, log = tmp_path / "results", tmp_path / "sweep.log"
    args = ("seeds:=0-1", "nepisodes:=60", "nsteps:=100", "name:=killed", "eval_episodes:=1")
    sweep = results / "moving_cube" / "killed"
    temp_folders = set(Path("/tmp").glob("rrl-ray-*"))  # the cluster's nodes'
    driver = start_sweep(cluster, results, log, *args)

    def checkpointed_mid_run() -> list:
        """The trials with a checkpoint mid-run whose first learning_curve.png is written. The killed driver's trials
        get SIGTERM from their launch reapers, which SIGKILL 5 s later: a training stopped while it still imported
        matplotlib for its first curve (seconds on two busy cores) was killed before its summary.json (a flake)."""
        mid = []
        for seed in (0, 1):
            run = sweep / f"seed={seed}"
            try:
                episode = json.loads((run / "qtable.json").read_text())["episode"]
            except (OSError, ValueError):
                continue
            if 0 < episode < 60 and (run / "learning_curve.png").is_file():  # written after the checkpoint, whole
                mid.append(seed)
        return mid
    try:
        resumed = wait_for(checkpointed_mid_run, 300, f"a trial's first checkpoint (log {log})")[0]
    finally:
        os.kill(driver.pid, signal.SIGKILL)  # the driver lost: Ray ends its trials, PDEATHSIG their launches
        driver.wait(30)
    wait_for(lambda: not training_processes(cluster), 60, "the end of every training process of the killed sweep")
    assert set(Path("/tmp").glob("rrl-ray-*")) == temp_folders  # a driver in a cluster makes no Ray temp folder
    summary = json.loads((sweep / f"seed={resumed}" / "summary.json").read_text())
    assert summary["completed"] is False and 0 < summary["episodes"] < 60, summary

    code = finish(start_sweep(cluster, results, log, "name:=killed", "resume:=true"), log)
    output = log.read_text()
    assert code == 0, output[-4000:]
    for seed in (0, 1):
        run = sweep / f"seed={seed}"
        assert [row[0] for row in episodes(run)[1:]] == [str(n) for n in range(1, 61)]
        assert json.loads((run / "summary.json").read_text())["completed"] is True
    training_log = (sweep / "logs" / f"seed={resumed}" / "training.log").read_text()
    assert "Resuming" in training_log, training_log[-3000:]
    # The episodes up to the checkpoint are kept as they were, the same as the run alone; after it the sim's noise
    # restarts from its seed (robot_rl.training: the first episode of a resumed run), so the rest may differ.
    kept = summary["episodes"] + 1
    assert episodes(sweep / f"seed={resumed}")[:kept] == \
        episodes(run_alone(tmp_path, resumed, nepisodes=60, nsteps=100))[:kept]
    assert sum(line.startswith("| seed=") for line in (sweep / "sweep.md").read_text().splitlines()) == 2
    assert training_processes(cluster) == []


def test_a_trial_whose_node_is_lost_runs_again_from_its_checkpoint_on_the_other(tmp_path):
    """Tune's FailureConfig: the trial on the killed node fails and runs again on the head, resuming its run."""
    results, log = tmp_path / "results", tmp_path / "sweep.log"
    sweep = results / "moving_cube" / "lost"
    with LoopbackCluster(tmp_path / "cluster", nodes=2, cpus_per_node=1) as loopback:
        driver = start_sweep(loopback, results, log, "seeds:=0-1", "nepisodes:=60", "nsteps:=100", "name:=lost",
                             "eval_episodes:=1")
        try:
            def both_checkpointed() -> bool:
                return all((sweep / f"seed={seed}" / "qtable.json").is_file() for seed in (0, 1))
            wait_for(both_checkpointed, 300, f"both trials' first checkpoints (log {log})")
            loopback.kill_node(1)  # one trial runs on each node: the second node's is lost with it
            code = finish(driver, log)
        finally:
            if driver.poll() is None:
                os.killpg(driver.pid, signal.SIGKILL)
                driver.wait(30)
        output = log.read_text()
        assert code == 0, output[-4000:]
        assert "failed; it runs again from its checkpoint" in output, output[-3000:]
        resumed = [seed for seed in (0, 1)
                   if "Resuming" in (sweep / "logs" / f"seed={seed}" / "training.log").read_text()]
        assert len(resumed) == 1, output[-3000:]
        for seed in (0, 1):
            run = sweep / f"seed={seed}"
            assert [row[0] for row in episodes(run)[1:]] == [str(n) for n in range(1, 61)]
            assert json.loads((run / "summary.json").read_text())["completed"] is True
        wait_for(lambda: not training_processes(loopback), 60, "the end of every training process")
