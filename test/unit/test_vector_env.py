"""Vector envs on the direct backend (worker processes, no master): seeds per worker, the gymnasium
VectorEnv contract with SAME_STEP autoreset, determinism, errors in a worker, and no process left."""
import json
import os
import shutil
import signal
import subprocess
import sys
import time

import gymnasium
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

from hopper_training.envs.stay_up import STAY_UP
from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from robot_rl import EnvWorkers, WorkerError, as_env_actions, checked_actions, make_env, make_vector_env, worker_seeds


def alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def short(task, nsteps):
    return task.default_params().with_changes("test", nsteps=nsteps)


def test_worker_seeds_repeat_differ_and_fit_a_ros_int():
    seeds = worker_seeds(7, 4)
    assert seeds == worker_seeds(7, 4)
    assert len(set(seeds)) == 4
    assert worker_seeds(7, 2) == seeds[:2], "adding workers leaves the first workers' seeds alone"
    assert set(worker_seeds(8, 4)).isdisjoint(seeds)
    assert all(0 <= s < 2**31 for s in seeds + worker_seeds(None, 8))
    assert worker_seeds(None, 3) != worker_seeds(None, 3), "no seed: fresh entropy"


def test_bad_arguments_fail_with_one_clear_error():
    with pytest.raises(ValueError, match="number of envs must be a whole number >= 1, got 0"):
        EnvWorkers(ONE_DISK_WALK, 0, backend="direct")
    with pytest.raises(ValueError, match="backend must be 'ros' or 'direct', got 'gazebo'"):
        EnvWorkers(ONE_DISK_WALK, 1, backend="gazebo")


@pytest.mark.parametrize("task", [ONE_DISK_WALK, STAY_UP], ids=["cube", "hopper"])
def test_reset_step_close_contract(task):
    params = short(task, 5)
    env = make_vector_env(task, 2, backend="direct", seed=3, params=params)
    pids = [info["pid"] for info in env.workers.worker_info]
    try:
        assert env.num_envs == 2 and env.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
        assert [os.sched_getscheduler(pid) for pid in pids] == [os.SCHED_BATCH] * 2, \
            "workers run as SCHED_BATCH: waking one never preempts the parent before it wakes the next"
        assert os.sched_getscheduler(0) == os.SCHED_OTHER, "the parent keeps its class"
        assert env.single_observation_space == make_env(task, params=params).observation_space
        observations, infos = env.reset(seed=3)
        assert observations.shape == (2, *env.single_observation_space.shape)
        assert observations in env.observation_space
        assert infos["_sim_time"].all()
        ends = 0
        for step in range(1, 13):
            observations, rewards, terminations, truncations, infos = env.step(np.array([0, 1]))
            assert observations in env.observation_space
            assert rewards.dtype == np.float64 and terminations.dtype == truncations.dtype == np.bool_
            done = terminations | truncations
            if done.any():
                ends += int(done.sum())
                assert (infos["_final_obs"] == done).all()
                for i in np.flatnonzero(done):
                    assert infos["final_obs"][i] in env.single_observation_space
                    assert infos["final_info"]["_sim_time"][i], "the episode's last info is kept"
            if step % 5 == 0:
                assert truncations.all() or terminations.any(), "nsteps 5: every episode ends by step 5"
        assert ends >= 4, "the envs reset themselves and went on (SAME_STEP autoreset)"
    finally:
        env.close()
    assert not any(alive(pid) for pid in pids), "close() ends every worker"
    with pytest.raises(WorkerError, match="closed"):
        env.workers.send(0, "step", 0)


def test_same_seed_same_trajectories_and_each_worker_its_own():
    def run(seed):
        env = make_vector_env(ONE_DISK_WALK, 2, backend="direct", seed=seed, params=short(ONE_DISK_WALK, 50))
        try:
            trajectory = [env.reset(seed=seed)[0]]
            for action in [0, 0, 3, 1, 2, 4, 0, 0]:
                trajectory.append(env.step([action, action])[0])
            return np.array(trajectory)
        finally:
            env.close()
    first, again, other = run(5), run(5), run(6)
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(first[:, 0], first[:, 1]), "each worker has its own noise seed"
    assert not np.array_equal(first, other)


def test_an_exception_in_a_worker_names_it_and_the_others_close_cleanly():
    env = make_vector_env(ONE_DISK_WALK, 2, backend="direct", seed=0, params=short(ONE_DISK_WALK, 50))
    pids = [info["pid"] for info in env.workers.worker_info]
    try:
        env.reset(seed=0)
        env.workers.send(0, "step", 0)
        env.workers.send(1, "step", 99)  # past the vector env's own check of the actions
        with pytest.raises(WorkerError, match=r"worker 1 \(direct\) failed: ValueError: action 99 is not in") as error:
            env.workers.receive_all()
    finally:
        env.close()
    assert not any(alive(pid) for pid in pids)
    message = str(error.value)
    assert "\n" not in message, "one line: the traceback goes to the worker's log folder"
    folder = env.workers.log_dir / "worker1"
    assert message.endswith(f"its traceback (if any) are kept in {folder}")
    try:
        assert "Traceback" in (folder / "traceback.txt").read_text(), "kept where the error says"
    finally:
        shutil.rmtree(env.workers.log_dir)


ORPHANED_WORKERS = """
import sys
from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from robot_rl import EnvWorkers
if __name__ == "__main__":
    workers = EnvWorkers(ONE_DISK_WALK, 2, backend="direct", seed=0)
    print(*[info["pid"] for info in workers.worker_info], flush=True)
    sys.stdin.read()  # until the test kills this process
"""


def test_the_workers_of_a_parent_killed_with_sigkill_end_and_remove_its_temporary_folder(tmp_path):
    temporary = tmp_path / "tmp"
    temporary.mkdir()
    parent = subprocess.Popen([sys.executable, "-c", ORPHANED_WORKERS], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                              text=True, env={**os.environ, "TMPDIR": str(temporary)})
    try:
        pids = [int(pid) for pid in parent.stdout.readline().split()]
        assert len(pids) == 2 and len(list(temporary.iterdir())) == 1, "the workers' folder"
    finally:
        parent.kill()
        parent.wait(10)
    deadline = time.monotonic() + 30.0
    while any(alive(pid) for pid in pids) or list(temporary.iterdir()):
        assert time.monotonic() < deadline, f"left: {[p for p in pids if alive(p)]}, {list(temporary.iterdir())}"
        time.sleep(0.05)  # processes of another process: nothing notifies their end


@pytest.mark.parametrize("actions, expected", [
    ([0, 99], r"action 99 of env 1 is not in Discrete\(5\)"),
    ([0, 2.5], r"action 0.0 of env 0 is not in Discrete\(5\)"),  # a float array: none of its actions is whole
    ([0, 1, 2], r"3 actions for 2 envs"),
])
def test_a_bad_action_is_refused_before_any_worker_steps_and_the_workers_go_on(actions, expected):
    env = make_vector_env(ONE_DISK_WALK, 2, backend="direct", seed=0, params=short(ONE_DISK_WALK, 50))
    try:
        first, _ = env.reset(seed=0)
        with pytest.raises(ValueError, match=expected):
            env.step(actions)
        observations, *_ = env.step(np.array([1, 2]))
        assert observations.shape == first.shape
    finally:
        env.close()


def test_actions_take_the_form_of_their_space():
    box = gymnasium.spaces.Box(-1.0, 1.0, (3,), np.float32)
    actions = as_env_actions(np.arange(6, dtype=np.float64).reshape(2, 3), box, 2)
    assert [a.dtype for a in actions] == [np.float32] * 2 and actions[1].tolist() == [3.0, 4.0, 5.0]
    assert as_env_actions(np.array([4, 1]), gymnasium.spaces.Discrete(5), 2) == [4, 1]
    assert type(as_env_actions(np.int64(3), gymnasium.spaces.Discrete(5), 1)[0]) is int
    with pytest.raises(ValueError, match="5 action values for 2 envs of Box"):
        as_env_actions(np.zeros(5), box, 2)
    with pytest.raises(ValueError, match=r"action \[2.0, 0.0, 0.0\] of env 0 is not in Box"):
        checked_actions(np.array([[2.0, 0, 0], [0, 0, 0]]), box, 2)


def step_with_one_stopped(workers: EnvWorkers, stopped: int) -> None:
    """Reset both workers, stop worker `stopped` (SIGSTOP), then send each a step: one cannot answer."""
    workers.request_all("reset", [(0, None), (1, None)])
    os.kill(workers.worker_info[stopped]["pid"], signal.SIGSTOP)
    for i in range(2):
        workers.send(i, "step", 0)


def test_a_worker_that_does_not_answer_in_time_is_named_and_the_others_replies_are_read():
    workers = EnvWorkers(ONE_DISK_WALK, 2, backend="direct", seed=0)
    pids = [info["pid"] for info in workers.worker_info]
    try:
        try:
            step_with_one_stopped(workers, 1)
            with pytest.raises(WorkerError, match=rf"worker 1 \(direct, pid {pids[1]}\) did not answer a step "
                                                  r"within 1 s \(is the machine overloaded"):
                workers.receive_all(timeout=1.0, what="answer a step")
            assert workers._pending == [False, True]  # worker 0's reply was read, worker 1's is still owed
        finally:
            os.kill(pids[1], signal.SIGCONT)
        assert len(workers.receive(1, what="answer a step")) == 6  # the late reply, still in step with the worker
        assert [len(reply) for reply in workers.request_all("step", [0, 0])] == [6, 6]
    finally:
        workers.close()
    assert not any(alive(pid) for pid in pids)


def test_a_worker_that_dies_is_named_with_its_exit_code():
    workers = EnvWorkers(ONE_DISK_WALK, 2, backend="direct", seed=0)
    pids = [info["pid"] for info in workers.worker_info]
    died = r"worker 0 \(direct\) died \(exit code -9\) before its answer a step"
    try:
        step_with_one_stopped(workers, 0)
        os.kill(pids[0], signal.SIGKILL)
        with pytest.raises(WorkerError, match=died):  # as a vector step reads the replies
            workers.receive_all(what="answer a step")
        with pytest.raises(WorkerError, match=died):  # as the Q-learning trainer reads one
            workers.receive(0, what="answer a step")
    finally:
        workers.close()
    assert not any(alive(pid) for pid in pids)


def test_a_worker_that_cannot_make_its_env_fails_the_start_with_its_error(tmp_path):
    with pytest.raises(WorkerError, match="worker 0 \\(direct\\) failed: .*render_mode must be one of"):
        EnvWorkers(ONE_DISK_WALK, 1, backend="direct", render_mode="holographic")


def vector_train(tmp_path, nepisodes, resume=False, log=None, run_name="run"):
    from robot_rl import RunDirectory, TrainingHooks, VectorQLearningTrainer
    params = short(ONE_DISK_WALK, 15).with_changes("test", nepisodes=nepisodes)
    run = RunDirectory(tmp_path / "moving_cube" / run_name) if resume else \
        RunDirectory.create(tmp_path, "moving_cube", params.to_mapping(), ONE_DISK_WALK.metric_names, run_name)
    env = make_vector_env(ONE_DISK_WALK, 2, backend="direct", seed=params.seed, params=params)
    lines = [] if log is None else log
    try:
        trainer = VectorQLearningTrainer(env, ONE_DISK_WALK, params, run,
                                         TrainingHooks(log=lines.append, checkpoint_every=3), resume)
        return run, trainer.train()
    finally:
        env.close()


def test_tabular_q_learning_from_two_envs_fills_one_table_and_repeats(tmp_path):
    log = []
    run, summary = vector_train(tmp_path / "a", 6, log=log)
    records = run.read_episodes()
    assert [r.episode for r in records] == [1, 2, 3, 4, 5, 6] and summary["completed"]
    episode_lines = [line for line in log if line.startswith("EP: ")]
    assert len(episode_lines) == 6 and episode_lines[-1].endswith("(episodes per env: 3, 3)")
    assert {line.split(" - env ")[1][:3] for line in episode_lines} == {"1/2", "2/2"}
    assert [round(r.epsilon, 6) for r in records] == sorted((round(r.epsilon, 6) for r in records), reverse=True)
    checkpoint = json.loads(run.qtable_json.read_text())
    assert checkpoint["episode"] == 6 and checkpoint["state"]["env_steps"] == sum(r.steps for r in records)
    again, _ = vector_train(tmp_path / "b", 6)
    assert [(r.steps, r.return_) for r in again.read_episodes()] == [(r.steps, r.return_) for r in records]
    assert json.loads(again.qtable_json.read_text())["qlearn"] == checkpoint["qlearn"]


def test_tabular_q_learning_from_two_envs_resumes(tmp_path):
    run, _ = vector_train(tmp_path, 3)
    log = []
    _, summary = vector_train(tmp_path, 7, resume=True, log=log)
    assert log[0].startswith(f"Resuming {run.path} after episode 3")
    assert [r.episode for r in run.read_episodes()] == list(range(1, 8)) and summary["episodes"] == 7
