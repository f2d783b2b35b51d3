"""Vector envs over ROS: each worker on a master and a sim node of its own, stepping in parallel and
giving the direct backend's observations; every process they start is gone after close, after an
exception in a worker and after SIGINT to the process group; training from N envs and deep agents
through the training launch (tabular from 2 envs; a short DQN run writes every results file and resumes)."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import rosgraph
import yaml

from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from robot_rl import WorkerError, make_vector_env
from workspace_tools.launch_reaper import descendants
from workspace_tools.paths import PROGRAMS, REPO
from workspace_tools.processes import Processes, RosMaster, launch_args

CONFIG = ONE_DISK_WALK.config_path


def alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # a zombie is gone too, only not yet reaped
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def wait_gone(pids, timeout=20.0):
    end = time.monotonic() + timeout
    while any(alive(pid) for pid in pids):
        if time.monotonic() > end:
            left = [Path(f"/proc/{p}/cmdline").read_bytes().replace(b"\0", b" ")[:100] for p in pids if alive(p)]
            raise AssertionError(f"processes still running {timeout} s after the end: {left}")
        time.sleep(0.05)


def all_pids(env):
    return [pid for info in env.workers.worker_info for pid in (info["pid"], *info["children"])]


def short_params(**changes):
    return ONE_DISK_WALK.default_params().with_changes("test", **{"nsteps": 6, **changes})


def test_two_ros_workers_step_in_parallel_on_masters_of_their_own_as_direct_workers_do(tmp_path):
    actions = [[0, 1], [3, 4], [0, 0], [2, 1], [1, 3], [0, 0], [4, 4], [1, 0]]

    def trajectory(backend):
        env = make_vector_env(ONE_DISK_WALK, 2, backend=backend, seed=9, params=short_params(), log_dir=tmp_path)
        try:
            if backend == "ros":
                uris = [info["master_uri"] for info in env.workers.worker_info]
                assert len(set(uris)) == 2 and all(uri.startswith("http://127.0.0.1:") for uri in uris)
                for uri in uris:  # each master knows its own sim node, under the tutorials' global names
                    master = rosgraph.Master("/test", master_uri=uri)
                    assert master.lookupService("/pybullet_sim/step").startswith("rosrpc://127.0.0.1:")
                    assert any(topic == "/moving_cube/odom" for topic, _ in master.getPublishedTopics("/"))
                assert {os.sched_getscheduler(pid) for pid in all_pids(env)} == {os.SCHED_BATCH}, \
                    "each worker's master and sim node inherit its SCHED_BATCH class"
            observations, infos = env.reset(seed=9)
            start = infos["sim_time"]
            rows = [observations]
            for action in actions:
                observations, _, _, _, infos = env.step(action)
                rows.append(observations)
                if len(rows) == 2:  # both sims advanced exactly one running_step
                    np.testing.assert_allclose(infos["sim_time"] - start, [0.06, 0.06], atol=1e-9)
            return np.array(rows), all_pids(env)
        finally:
            env.close()

    ros, ros_pids = trajectory("ros")
    direct, _ = trajectory("direct")
    np.testing.assert_allclose(ros, direct, rtol=0, atol=1e-9)
    assert not np.array_equal(ros[:, 0], ros[:, 1]), "each worker has its own seed"
    assert len(ros_pids) == 6, "per worker: the worker, its master and its sim node"
    wait_gone(ros_pids)


def test_every_process_is_gone_after_an_exception_in_a_worker(tmp_path):
    env = make_vector_env(ONE_DISK_WALK, 2, backend="ros", seed=0, params=short_params(), log_dir=tmp_path,
                          ros_timeout=5.0)
    pids = all_pids(env)
    try:
        env.reset(seed=0)
        env.step([0, 0])
        os.kill(env.workers.worker_info[1]["children"][1], signal.SIGKILL)  # worker 1's sim node dies
        with pytest.raises(WorkerError, match=r"worker 1 \(ros\) failed: SimConnectionError: service "
                                              r"/pybullet_sim/step_packed failed"):
            env.step([0, 0])
    finally:
        env.close()
    wait_gone(pids)


def test_every_process_is_gone_after_sigint_to_the_process_group(tmp_path):
    log = tmp_path / "script.log"
    with open(log, "w") as err:
        script = subprocess.Popen([sys.executable, str(PROGRAMS / "vector_sigint.py"), str(tmp_path / "workers")],
                                  stdout=subprocess.PIPE, stderr=err, text=True, start_new_session=True)
    try:
        line = script.stdout.readline()  # bounded below: the script prints once its two workers step
        assert line, f"the script ended before its workers stepped:\n{log.read_text()[-3000:]}"
        pids = json.loads(line)
        assert len(pids) == 6 and all(alive(pid) for pid in pids)
        os.killpg(script.pid, signal.SIGINT)
        script.wait(30)
        wait_gone(pids)
    finally:
        if script.poll() is None:
            os.killpg(script.pid, signal.SIGKILL)
            script.wait()


def write_config(path, **changes):
    document = yaml.safe_load(CONFIG.read_text())
    document["moving_cube"].update(changes)
    path.write_text(yaml.safe_dump(document))
    return path


def train(master, results, config, log, **args):
    result = master.run(["rosrun", "workspace_tools", "roslaunch_checked.py", "moving_cube_training", "main.launch",
                         *launch_args(results_dir=results, config=config, **args)], timeout=600)
    log.write_text(result.stdout + result.stderr)
    assert result.returncode == 0, log.read_text()[-4000:]
    assert master.leftovers() == [], "every node of the launch is gone"
    return result.stdout + result.stderr


def test_tabular_q_learning_from_two_envs_over_ros(tmp_path):
    master = RosMaster(tmp_path / "ros", cwd=REPO)
    try:
        output = train(master, tmp_path / "results", write_config(tmp_path / "c.yaml", nsteps=15), tmp_path / "log",
                       envs=2, nepisodes=6, video="false")
    finally:
        master.close()
    run = tmp_path / "results" / "moving_cube" / "latest"
    for name in ("params.yaml", "episodes.csv", "qtable.json", "learning_curve.png", "summary.json"):
        assert (run / name).is_file(), name
    lines = [line for line in output.splitlines() if "EP: " in line]
    assert [int(line.split("EP: ")[1].split(" ")[0]) for line in lines] == [1, 2, 3, 4, 5, 6]
    assert any(" - env 1/2 (episodes per env: " in line for line in lines)
    assert any(" - env 2/2 (episodes per env: " in line for line in lines)
    assert lines[-1].endswith("(episodes per env: 3, 3)")
    summary = json.loads((run / "summary.json").read_text())
    assert summary["completed"] and summary["episodes"] == 6
    assert json.loads((run / "qtable.json").read_text())["episode"] == 6


def test_a_short_dqn_run_over_ros_writes_every_results_file_and_resumes(tmp_path):
    config = write_config(tmp_path / "c.yaml", nsteps=10)
    results = tmp_path / "results"
    master = RosMaster(tmp_path / "ros", cwd=REPO)
    try:
        train(master, results, config, tmp_path / "first.log", agent="dqn", nepisodes=4)
        run = (results / "moving_cube-dqn" / "latest").resolve()
        for name in ("params.yaml", "episodes.csv", "agent.json", "model.zip", "learning_curve.png",
                     "summary.json", "video.mp4"):
            assert (run / name).is_file(), name
        first = json.loads((run / "summary.json").read_text())
        assert (first["agent"], first["episodes"], first["completed"]) == ("dqn", 4, True)
        model = (run / "model.zip").read_bytes()
        output = train(master, results, config, tmp_path / "second.log", agent="dqn", nepisodes=7, resume="true",
                       video="false")
    finally:
        master.close()
    assert f"Resuming {run} after episode 4 ({first['env_steps']} env steps)" in output
    episodes = [line.split(",")[0] for line in (run / "episodes.csv").read_text().splitlines()[1:]]
    assert episodes == [str(n) for n in range(1, 8)]
    second = json.loads((run / "summary.json").read_text())
    assert second["completed"] and second["episodes"] == 7 and second["env_steps"] > first["env_steps"]
    assert json.loads((run / "agent.json").read_text())["episode"] == 7
    assert (run / "model.zip").read_bytes() != model
    runner = Processes(tmp_path / "eval", cwd=REPO)
    try:
        evaluation = runner.run(["rosrun", "moving_cube_training", "evaluate.py", "--run", str(run), "--episodes",
                                 "2", "--horizon-s", "1"], timeout=300)
    finally:
        runner.close()
    assert evaluation.returncode == 0, evaluation.stderr
    report = json.loads(evaluation.stdout.strip().splitlines()[-1])
    assert report["task"] == "MovingCubeOneDiskWalk-v0" and report["episodes"] == 2


def test_ctrl_c_on_a_training_from_two_envs_ends_every_process_and_saves_the_run(tmp_path):
    log = tmp_path / "run.log"
    master = RosMaster(tmp_path / "ros", cwd=REPO)
    try:
        with open(log, "w") as out:
            launch = master.start(["roslaunch", "moving_cube_training", "main.launch", *launch_args(
                results_dir=tmp_path / "results", config=write_config(tmp_path / "c.yaml", nsteps=15), envs=2,
                nepisodes=100000, video="false")], stdout=out, stderr=subprocess.STDOUT)
        end = time.monotonic() + 120
        while "EP: 4 " not in log.read_text():
            assert time.monotonic() < end and launch.poll() is None, f"no 4th episode:\n{log.read_text()[-3000:]}"
            time.sleep(0.1)
        pids = descendants(launch.pid)
        assert len(pids) >= 7, "the training node, 2 workers, their 2 masters and 2 sim nodes (and the launch's)"
        launch.send_signal(signal.SIGINT)  # Ctrl-C reaches roslaunch, which stops every node with SIGINT
        launch.wait(60)
        assert "training interrupted after episode" in log.read_text(), log.read_text()[-3000:]
        wait_gone(pids)
        assert master.leftovers() == []
    finally:
        master.close()
    summary = json.loads((tmp_path / "results" / "moving_cube" / "latest" / "summary.json").read_text())
    assert (summary["completed"], summary["stopped"]) == (False, "interrupted") and summary["episodes"] >= 4
