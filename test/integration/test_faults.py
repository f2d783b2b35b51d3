"""Faults and bad inputs, each on its own master, as a user meets them: every case asserts the one clear
line that says what is wrong, the exit code, that nothing was lost, and that no process is left.

The README's fault table lists every case of this file (its test ids in brackets)."""
from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest
import rosgraph
import yaml

from hopper_training.envs.stay_up import STAY_UP
from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from moving_cube_training.robot import MOVING_CUBE
from workspace_tools.bench.common import stat_fields
from workspace_tools.launch_reaper import descendants
from workspace_tools.paths import PROGRAMS, REPO
from workspace_tools.processes import Processes, RosMaster, free_port, processes_using, stop, wait_for
from workspace_tools.training_launch import write_cube_training_launch

TRAIN = ["rosrun", "workspace_tools", "roslaunch_checked.py"]  # what ./ws run starts
CUBE_TRAINING = [*TRAIN, "moving_cube_training", "main.launch", "video:=false"]
HOPPER_TRAINING = [*TRAIN, "hopper_training", "main.launch", "video:=false"]
CUBE_URDF = MOVING_CUBE.urdf_path.read_text()
CUBE_SIM = yaml.safe_load(MOVING_CUBE.sim_config_path.read_text())
INTERRUPTED = 130


# -- helpers --------------------------------------------------------------------------------------


def cube_config(path: Path, **changes) -> Path:
    document = yaml.safe_load(ONE_DISK_WALK.config_path.read_text())
    document["moving_cube"].update(changes)
    path.write_text(yaml.safe_dump(document))
    return path


def one_line(output: str, text: str) -> str:
    """The one line of `output` that says `text` (roslaunch's screen output repeats nothing else)."""
    lines = [line for line in output.splitlines() if text in line]
    assert len(lines) == 1, f"expected one line with {text!r}, got {len(lines)}:\n{output[-4000:]}"
    assert "Traceback" not in output, output[-4000:]
    return lines[0]


def node_pid(master: RosMaster, name: str) -> int:
    """The pid of a node, from `rosnode info` (the master knows every node's XML-RPC address)."""
    info = master.run(["rosnode", "info", name], timeout=30).stdout
    return int(next(line.split()[-1] for line in info.splitlines() if line.startswith("Pid:")))


def run_files(results: Path, task: str = "moving_cube") -> dict:
    """Every file of the latest run, as bytes."""
    run = results / task / "latest"
    return {p.name: p.read_bytes() for p in sorted(run.iterdir())} if run.exists() else {}


def episodes(results: Path, task: str = "moving_cube") -> list[int]:
    lines = (results / task / "latest" / "episodes.csv").read_text().split("\n")[1:-1]
    return [int(line.split(",")[0]) for line in lines]


# -- parameters and configuration (the training node, before anything is written) ----------------

@pytest.mark.parametrize("changes, expected", [
    ({"alpha": None}, "missing parameter 'alpha'"),
    ({"alpha": "high"}, "parameter 'alpha' expected float, got 'high' (str)"),
    ({"alpha": 1.5}, "parameter 'alpha' = 1.5 out of range [0.0, 1.0]"),
    ({"running_step": -0.06}, "parameter 'running_step' = -0.06 out of range (0.0, 100.0]"),
    ({"init_cube_pose": {"x": 0.0, "y": 0.0}}, "missing parameter 'init_cube_pose/z'"),
    ({"running_step": 1e308}, "parameter 'running_step' = 1e+308 out of range (0.0, 100.0]"),
    ({"nsteps": 2 * 10**9}, "parameter 'nsteps' = 2000000000 out of range [1, 1000000000]"),
    ({"alpah": 0.5}, "unknown parameter 'alpah' (known: alpha, gamma,"),
], ids=["missing_key", "wrong_type", "out_of_range", "negative_step", "missing_nested_key", "absurd_running_step",
        "absurd_nsteps", "unknown_key"])
def test_bad_param_stops_training_before_anything_is_written(master, tmp_path, changes, expected):
    document = yaml.safe_load(ONE_DISK_WALK.config_path.read_text())
    for key, value in changes.items():
        if value is None:
            del document["moving_cube"][key]
        else:
            document["moving_cube"][key] = value
    config = tmp_path / "bad.yaml"
    config.write_text(yaml.safe_dump(document))
    result = master.run([*CUBE_TRAINING, f"config:={config}", f"results_dir:={tmp_path / 'results'}"], timeout=120)
    output = result.stdout + result.stderr
    assert result.returncode == 1, output[-3000:]
    assert str(config) in one_line(output, expected)
    assert not (tmp_path / "results").exists(), "nothing may be written before the params are valid"


def test_duplicate_key_in_the_config_is_refused(master, tmp_path):
    config = tmp_path / "dup.yaml"
    config.write_text(ONE_DISK_WALK.config_path.read_text().replace("  alpha: 0.1", "  alpha: 0.1\n  alpha: 0.9"))
    result = master.run([*CUBE_TRAINING, f"config:={config}", f"results_dir:={tmp_path / 'results'}"], timeout=120)
    assert result.returncode == 1
    one_line(result.stdout + result.stderr, f"{config}: duplicate key 'alpha' at line")
    assert not (tmp_path / "results").exists()


@pytest.mark.parametrize("content, expected", [
    ("moving_cube:\n  alpha: [0.1\n", "contains invalid YAML"),
    (None, "file does not exist"),
], ids=["malformed_yaml", "missing_config_file"])
def test_config_roslaunch_cannot_load_gives_one_line(master, tmp_path, content, expected):
    config = tmp_path / "config.yaml"
    if content is not None:
        config.write_text(content)
    result = master.run([*CUBE_TRAINING, f"config:={config}", f"results_dir:={tmp_path / 'results'}"], timeout=120)
    output = result.stdout + result.stderr
    assert result.returncode == 1, output
    assert one_line(output, expected).startswith("roslaunch_checked.py: cannot launch ")
    assert len(output.strip().splitlines()) <= 3, output


def test_a_config_with_rosparams_evaluated_tag_is_refused_before_it_runs(master, tmp_path):
    """rosparam evaluates !radians with eval() when roslaunch loads a YAML file: ./ws run refuses the tag."""
    marker = tmp_path / "marker"
    config = tmp_path / "config.yaml"
    config.write_text(ONE_DISK_WALK.config_path.read_text().replace(
        "alpha:", f'alpha: !radians __import__("os").system("touch {marker}") or 0.1\n  unused_alpha:', 1))
    result = master.run([*CUBE_TRAINING, f"config:={config}", f"results_dir:={tmp_path / 'results'}"], timeout=120)
    output = result.stdout + result.stderr
    assert result.returncode == 1, output
    line = one_line(output, "is not allowed in a config (rosparam would evaluate it as Python code)")
    assert line.startswith("roslaunch_checked.py: cannot launch "), line
    assert not marker.exists() and not (tmp_path / "results").exists()


@pytest.mark.parametrize("args, expected", [
    (["nepisodes:=0"], "parameter 'nepisodes' = 0 out of range [1, 1000000000]"),
    (["nepisodes:=many"], "parameter 'nepisodes' expected int, got 'many' (str)"),
    (["nepisodes:=100000000000000000000"], "parameter 'nepisodes' = 100000000000000000000 out of range"),
    (["seed:=2147483648"], "parameter 'seed' = 2147483648 out of range [0, 2147483647]"),
    (["seed:=-1"], "parameter 'seed' = -1 out of range [0, 2147483647]"),
    (["envs:=abc"], "parameter 'envs' expected int, got 'abc' (str)"),
    (["envs:=0"], "parameter 'envs' = 0 out of range [1, inf]"),
    ([f"envs:={2 * (os.cpu_count() or 1) + 1}"], "per core"),
    (["max_steps:=1e21"], "parameter 'max_steps' expected int, got '1e21' (str)"),
], ids=["nepisodes_zero", "nepisodes_text", "nepisodes_beyond_32_bits", "seed_beyond_32_bits", "seed_negative",
        "envs_text", "envs_zero", "envs_beyond_the_cores", "max_steps_text"])
def test_bad_launch_argument_gives_one_line(master, tmp_path, args, expected):
    result = master.run([*CUBE_TRAINING, *args, f"results_dir:={tmp_path / 'results'}"], timeout=120)
    output = result.stdout + result.stderr
    assert result.returncode == 1, output[-3000:]
    assert "/movingcube_gym" in one_line(output, expected)
    assert not (tmp_path / "results").exists()


def test_a_config_number_beyond_ros_ints_gives_one_line(master, tmp_path):
    """nsteps: 10**21 in the YAML: roslaunch cannot send it to the master (XML-RPC carries 32-bit ints)."""
    config = cube_config(tmp_path / "config.yaml", nsteps=10**21)
    result = master.run([*CUBE_TRAINING, f"config:={config}", f"results_dir:={tmp_path / 'results'}"], timeout=120)
    output = result.stdout + result.stderr
    assert result.returncode == 1, output[-3000:]
    line = one_line(output, "roslaunch_checked.py: cannot launch")
    assert "a ROS param is a 32-bit int at most: /moving_cube/nsteps" in line, line
    assert not (tmp_path / "results").exists()


def test_a_deep_agents_buffer_beyond_reason_gives_one_line(master, tmp_path):
    agent_config = tmp_path / "dqn.yaml"
    document = yaml.safe_load((REPO / "robot_rl" / "config" / "dqn.yaml").read_text())
    document["buffer_size"] = 10**12
    agent_config.write_text(yaml.safe_dump(document))
    result = master.run([*CUBE_TRAINING, "agent:=dqn", f"agent_config:={agent_config}",
                         f"results_dir:={tmp_path / 'results'}"], timeout=180)
    output = result.stdout + result.stderr
    assert result.returncode == 1, output[-3000:]
    assert str(agent_config) in one_line(output, "parameter 'buffer_size' = 1000000000000 out of range")
    assert not (tmp_path / "results").exists()


def test_an_adapting_attitude_assist_with_env_workers_gives_one_line_and_writes_nothing(master, tmp_path):
    """The assist's curriculum changes the one env of the trainer's process: two env workers are refused."""
    config = REPO / "hopper_training" / "config" / "end_to_end_assist.yaml"
    result = master.run([*HOPPER_TRAINING, "task:=end_to_end", "agent:=ppo", "backend:=direct", "envs:=2",
                         f"config:={config}", f"results_dir:={tmp_path / 'results'}"], timeout=240)
    output = result.stdout + result.stderr
    assert result.returncode == 1, output[-3000:]
    line = one_line(output, "attitude_assist/adapt_every (20) changes the sim's assist during the run")
    assert str(config) in line and "envs:=1 and an agent other than rllib_ppo" in line
    assert not (tmp_path / "results").exists()


def test_table_checks_on_two_env_workers_give_one_line_and_write_nothing(master, tmp_path):
    """The Q-table's checks play the trainer's one env: two env workers are refused before the run folder."""
    config = tmp_path / "hop_in_place_checked.yaml"
    document = yaml.safe_load((REPO / "hopper_training" / "config" / "hop_in_place.yaml").read_text())
    config.write_text(yaml.safe_dump({**document, "selection": {"every": 10}}))
    result = master.run([*HOPPER_TRAINING, "task:=hop_in_place", "backend:=direct", "envs:=2", f"config:={config}",
                         f"results_dir:={tmp_path / 'results'}"], timeout=240)
    output = result.stdout + result.stderr
    assert result.returncode == 1, output[-3000:]
    line = one_line(output, "parameter 'selection/every' (10) checks the Q-table during training")
    assert str(config) in line and "agent:=qlearn with envs:=1 only (this run: agent:=qlearn, envs:=2)" in line
    assert not (tmp_path / "results").exists()


@pytest.mark.parametrize("launch, args, folder, expected", [
    (HOPPER_TRAINING, ["task:=residual_forward", "agent:=dqn"], "residual_forward-dqn",
     "agent dqn on MonopedResidualForward-v0: DQN needs Discrete actions, the task has Box("),
    (CUBE_TRAINING, ["agent:=sac"], "moving_cube-sac",
     "agent sac on MovingCubeOneDiskWalk-v0: SAC needs Box (continuous) actions"),
    (CUBE_TRAINING, ["agent:=dqn", "buffer_size: 1000000000"], "moving_cube-dqn",
     "agent dqn on MovingCubeOneDiskWalk-v0: the agent's buffer needs"),
], ids=["dqn_on_box_actions", "sac_on_discrete_actions", "buffer_beyond_the_memory"])
def test_an_agent_that_cannot_train_the_task_writes_nothing(master, tmp_path, launch, args, folder, expected):
    """Refused before the run folder is made: no folder, `latest` unchanged."""
    results = tmp_path / "results"
    launch_args = [arg for arg in args if ":=" in arg]
    if "buffer_size: 1000000000" in args:  # in range (at most 10**9), beyond this machine's memory
        agent_config = tmp_path / "dqn.yaml"
        document = yaml.safe_load((REPO / "robot_rl" / "config" / "dqn.yaml").read_text())
        document["buffer_size"] = 10**9
        agent_config.write_text(yaml.safe_dump(document))
        launch_args.append(f"agent_config:={agent_config}")
    runs = results / folder
    (runs / "before").mkdir(parents=True)
    (runs / "latest").symlink_to("before")
    result = master.run([*launch, *launch_args, f"results_dir:={results}"], timeout=240)
    output = result.stdout + result.stderr
    assert result.returncode == 1, output[-3000:]
    one_line(output, expected)
    assert sorted(p.name for p in runs.iterdir()) == ["before", "latest"], "no run folder"
    assert os.readlink(runs / "latest") == "before" and not any((runs / "before").iterdir())


def test_unknown_task_names_the_known_ones(master, tmp_path):
    result = master.run([*HOPPER_TRAINING, "task:=fly", f"config:={STAY_UP.config_path}",
                         f"results_dir:={tmp_path / 'results'}"], timeout=120)
    assert result.returncode == 1
    one_line(result.stdout + result.stderr,
             "unknown task 'fly' (known: stay_up, hop, hop_in_place, residual_in_place, residual_forward, end_to_end)")


@pytest.mark.parametrize("args, expected", [
    (["run", "drone"], "unknown robot 'drone' (known: cube, hopper; see ./ws help)"),
    (["run", "cube", "nepisodes=5"], "'nepisodes=5' is not a launch argument NAME:=VALUE (see ./ws help)"),
    (["frobnicate"], "unknown command 'frobnicate'"),
], ids=["unknown_robot", "argument_without_colon_equals", "unknown_command"])
def test_ws_refuses_bad_arguments_with_one_line(tmp_path, args, expected):
    runner = Processes(tmp_path, cwd=REPO)
    try:
        result = runner.run([str(REPO / "ws"), *args], timeout=120)
    finally:
        runner.close()
    assert result.returncode in (1, 2), result.stderr
    assert one_line(result.stderr, expected).startswith("[ws] error: ")


# -- the sim node --------------------------------------------------------------------------------

def start_sim(master: RosMaster, private_params: dict, robot_description: str | None):
    """Run the sim node alone with the given params; return its completed process (it should exit)."""
    if robot_description is not None:
        master.params.setParam("/robot_description", robot_description)
    master.params.setParam("/pybullet_sim", private_params)
    return master.run(["rosrun", "pybullet_sim", "sim_node.py"], timeout=60)


def with_controller_joint(joint: str) -> dict:
    params = yaml.safe_load(yaml.safe_dump(CUBE_SIM))
    params["controllers"]["inertia_wheel_roll_joint_velocity_controller"]["joint"] = joint
    return params


@pytest.mark.parametrize("description, params, expected", [
    (None, CUBE_SIM, "parameter /robot_description is missing"),
    ("<robot name='cube'><link name='a'>", CUBE_SIM, "parameter /robot_description is not valid XML"),
    ("<sdf version='1.6'/>", CUBE_SIM, "is not a URDF"),
    (CUBE_URDF, with_controller_joint("no_such_joint"), "names joint 'no_such_joint'"),
    (CUBE_URDF, {**CUBE_SIM, "time_step": "fast"}, "parameter ~time_step must be float"),
    (CUBE_URDF, {**CUBE_SIM, "sensors": {"odom": {"type": "sonar"}}}, "unsupported sensor type"),
    (CUBE_URDF, {**CUBE_SIM, "seed": -1}, "parameter ~seed must be >= 0, got -1"),
    (CUBE_URDF, {**CUBE_SIM, "time_step": 1e30}, "parameter ~time_step must be <= 1, got 1e+30"),
    (CUBE_URDF, {**CUBE_SIM, "command_timeout": 1e30}, "parameter ~command_timeout must be <= 3600, got 1e+30"),
    (CUBE_URDF, {**CUBE_SIM, "spawn": {"yaw": 90.0}}, "parameter /pybullet_sim/spawn/yaw must be <= 6.28319, got 90.0"),
], ids=["missing_description", "broken_xml", "not_urdf", "unknown_joint", "mistyped_param", "unknown_sensor",
        "negative_seed", "absurd_time_step", "absurd_command_timeout", "spawn_yaw_in_degrees"])
def test_bad_sim_input_stops_the_sim_node_with_one_line(master, description, params, expected):
    result = start_sim(master, params, description)
    assert result.returncode == 1
    error = one_line(result.stdout + result.stderr, "pybullet_sim cannot start:")
    assert error.startswith("[FATAL]") and expected in error, result.stderr


def test_a_urdf_that_is_not_xml_stops_training_with_the_sims_error_only(master, tmp_path):
    """The sim's error is the one line; the training node says nothing misleading about waiting for it."""
    urdf = tmp_path / "broken.urdf"
    urdf.write_text("<robot name='moving_cube'><link name='a'>")
    sim_launch = tmp_path / "broken_sim.launch"
    sim_launch.write_text(f"""<launch>
  <arg name="paused"/><arg name="seed"/><arg name="gui"/><arg name="robot_state_publisher"/><arg name="rviz"/>
  <include file="$(find pybullet_sim)/launch/sim.launch" pass_all_args="true">
    <arg name="urdf" value="{urdf}"/>
    <arg name="sim_config" value="$(find moving_cube_description)/config/moving_cube_sim.yaml"/>
    <arg name="joint_states" value="/moving_cube/joint_states"/>
  </include>
</launch>""")
    training = write_cube_training_launch(tmp_path / "training.launch", sim_launch, ONE_DISK_WALK.config_path,
                                          tmp_path / "results")
    result = master.run([*TRAIN, str(training)], timeout=120)
    output = result.stdout + result.stderr
    assert result.returncode == 1, output[-3000:]
    line = one_line(output, "[FATAL]")
    assert "pybullet_sim cannot start: parameter /robot_description is not valid XML" in line
    assert "not available after" not in output, output[-3000:]


def test_a_sim_started_where_another_robots_sim_ran_starts_clean(master, tmp_path):
    """The cube sim's private params (its wheel controller) must not leak into the hopper's sim."""
    log = tmp_path / "cube.log"
    with open(log, "w") as out:
        cube = master.start(["roslaunch", "pybullet_sim", "cube_sim.launch", "robot_state_publisher:=false"],
                            stdout=out, stderr=subprocess.STDOUT)
    wait_for(lambda: "/pybullet_sim/step" in str(master.params.getSystemState()[2]), 60, "the cube sim")
    cube.send_signal(signal.SIGINT)
    cube.wait(30)
    with open(tmp_path / "hopper.log", "w") as out:
        master.start(["roslaunch", "pybullet_sim", "hopper_sim.launch", "robot_state_publisher:=false"],
                     stdout=out, stderr=subprocess.STDOUT)
    wait_for(lambda: "/pybullet_sim/step" in str(master.params.getSystemState()[2]), 60,
             "the hopper sim (after the cube's)")
    controllers = master.params.getParam("/pybullet_sim/controllers")
    assert "inertia_wheel_roll_joint_velocity_controller" not in controllers
    assert "haa_joint_position_controller" in controllers
    master.close()


# -- checkpoints and resume ----------------------------------------------------------------------

@pytest.fixture(scope="module")
def trained_run(tmp_path_factory):
    """A finished 12-episode cube run (checkpoint at 10 and 12)."""
    tmp = tmp_path_factory.mktemp("trained")
    master = RosMaster(tmp / "ros", cwd=REPO)
    try:
        config = cube_config(tmp / "config.yaml", nepisodes=12, nsteps=40)
        result = master.run([*CUBE_TRAINING, f"config:={config}", f"results_dir:={tmp / 'results'}"], timeout=180)
    finally:
        master.close()
    assert result.returncode == 0, (result.stdout + result.stderr)[-3000:]
    return tmp / "results", config


def copy_run(trained_run, tmp_path) -> tuple[Path, Path]:
    results, config = trained_run
    copy = tmp_path / "results"
    subprocess.run(["cp", "-a", str(results), str(copy)], check=True)
    return copy, config


@pytest.mark.parametrize("checkpoint, expected", [
    ({"format": "robot_rl.training_checkpoint/1", "episode": 10}, "not a usable checkpoint: format is"),
    ({"format": "something else", "episode": 0}, "not a usable checkpoint: format is"),
    ({"format": "robot_rl.training_checkpoint/2", "episode": 10}, "not a usable checkpoint: missing 'task'"),
    (b"\x89PNG\r\n\x1a\n\x00\xff\xfe random bytes", "not a checkpoint (not UTF-8 text)"),
    ([1, 2, 3], "not a checkpoint (a JSON list, not an object)"),
    ("{\"format\": ", "invalid JSON"),
], ids=["old_format_episode_10", "wrong_format_episode_0", "no_task", "random_bytes", "json_list", "truncated_json"])
def test_a_bad_checkpoint_is_refused_and_nothing_is_lost(master, trained_run, tmp_path, checkpoint, expected):
    results, config = copy_run(trained_run, tmp_path)
    qtable = results / "moving_cube" / "latest" / "qtable.json"
    qtable.write_bytes(checkpoint if isinstance(checkpoint, bytes) else
                       checkpoint.encode() if isinstance(checkpoint, str) else json.dumps(checkpoint).encode())
    before = run_files(results)
    result = master.run([*CUBE_TRAINING, f"config:={config}", f"results_dir:={results}", "resume:=true"],
                        timeout=120)
    output = result.stdout + result.stderr
    assert result.returncode == 1, output[-3000:]
    assert str(qtable.resolve()) in one_line(output, expected)
    assert run_files(results) == before, "a refused checkpoint must not change any file of the run"
    assert episodes(results) == list(range(1, 13))


@pytest.mark.parametrize("previous", ["none", "without_checkpoint"])
def test_resume_with_nothing_to_resume_gives_one_line(master, tmp_path, previous):
    results = tmp_path / "results"
    expected = "no previous run under"
    if previous == "without_checkpoint":  # made by another process: the one that creates a run holds its lock
        subprocess.run([sys.executable, "-c", "from robot_rl import RunDirectory; "
                        f"RunDirectory.create({str(results)!r}, 'moving_cube', {{'nepisodes': 3}}, run_name='r')"],
                       check=True, timeout=60)
        expected = f"no checkpoint {results / 'moving_cube' / 'r' / 'qtable.json'}"
    result = master.run([*CUBE_TRAINING, f"results_dir:={results}", "resume:=true"], timeout=120)
    assert result.returncode == 1
    one_line(result.stdout + result.stderr, expected)


def test_resume_of_another_task_is_refused(master, trained_run, tmp_path):
    """The hopper's stay-up training resuming a cube run: its task is named in the checkpoint."""
    results, _ = copy_run(trained_run, tmp_path)
    (results / "stay_up").mkdir()
    (results / "stay_up" / "latest").symlink_to(results / "moving_cube" / "latest")
    before = run_files(results)
    result = master.run([*HOPPER_TRAINING, f"results_dir:={results}", "resume:=true"], timeout=120)
    assert result.returncode == 1
    one_line(result.stdout + result.stderr, "it is of task 'MovingCubeOneDiskWalk-v0', this run trains 'Monoped-v0'")
    assert run_files(results) == before


def test_two_resumes_of_one_run_at_once_one_is_refused_and_the_run_stays_whole(tmp_path, trained_run):
    """Two `resume:=true` of one run folder, each on its own master: the one that comes second is refused
    with one line (the run's lock), the other finishes; every episode is in episodes.csv once."""
    results, config = copy_run(trained_run, tmp_path)
    masters = [RosMaster(tmp_path / f"ros{i}", cwd=REPO) for i in range(2)]
    logs = [tmp_path / f"run{i}.log" for i in range(2)]
    try:
        launches = []
        for m, log in zip(masters, logs):
            with open(log, "w") as out:
                launches.append(m.start([*CUBE_TRAINING, f"config:={config}", f"results_dir:={results}",
                                         "resume:=true", "nepisodes:=80"], stdout=out, stderr=subprocess.STDOUT))
        codes = [launch.wait(300) for launch in launches]
        assert all(m.leftovers() == [] for m in masters)
    finally:
        for m in masters:
            m.close()
    outputs = [log.read_text() for log in logs]
    assert sorted(codes) == [0, 1], (codes, [o[-2000:] for o in outputs])
    refused = outputs[codes.index(1)]
    line = one_line(refused, "another process is training this run")
    assert "[FATAL]" in line and str((results / "moving_cube" / "latest").resolve()) in line
    one_line(outputs[codes.index(0)], "Training complete: 80 episodes")
    assert episodes(results) == list(range(1, 81)), "every episode once"


def test_named_runs_are_kept_apart_and_resumed_by_name(master, tmp_path):
    """run:=first, then another run (latest moves on): run:=first again is refused, resume:=true run:=first
    continues first, not latest."""
    config = cube_config(tmp_path / "config.yaml", nepisodes=3, nsteps=10)
    results = tmp_path / "results"
    train = [*CUBE_TRAINING, f"config:={config}", f"results_dir:={results}"]
    for args in (["run:=first"], []):
        result = master.run([*train, *args], timeout=120)
        assert result.returncode == 0, (result.stdout + result.stderr)[-3000:]
    first = results / "moving_cube" / "first"
    before = {p.name: p.read_bytes() for p in first.iterdir()}
    again = master.run([*train, "run:=first"], timeout=120)
    assert again.returncode == 1
    line = one_line(again.stdout + again.stderr, f"a run {first} exists already")
    assert "resume:=true run:=first continues it" in line
    assert {p.name: p.read_bytes() for p in first.iterdir()} == before
    latest = (results / "moving_cube" / "latest").resolve()
    resumed = master.run([*train, "resume:=true", "run:=first", "nepisodes:=5"], timeout=120)
    assert resumed.returncode == 0, (resumed.stdout + resumed.stderr)[-3000:]
    one_line(resumed.stdout + resumed.stderr, f"Resuming {first} after episode 3")
    assert [line.split(",")[0] for line in (first / "episodes.csv").read_text().splitlines()[1:]] == \
        ["1", "2", "3", "4", "5"]
    assert len((latest / "episodes.csv").read_text().splitlines()) == 4, "latest is left alone"
    missing = master.run([*train, "resume:=true", "run:=second"], timeout=120)
    assert missing.returncode == 1
    one_line(missing.stdout + missing.stderr, "no run 'second' under")


@pytest.mark.parametrize("damage, expected", [
    ("missing", "no checkpoint"),
    ("random_bytes", "not a checkpoint (not UTF-8 text)"),
    ("no_params", "params.yaml"),
], ids=["missing_qtable", "corrupt_qtable", "missing_params"])
def test_evaluate_refuses_a_bad_run_with_one_line(trained_run, tmp_path, damage, expected):
    results, _ = copy_run(trained_run, tmp_path)
    run = results / "moving_cube" / "latest"
    if damage == "missing":
        (run / "qtable.json").unlink()
    elif damage == "random_bytes":
        (run / "qtable.json").write_bytes(b"\xff\xfe\x00\x81")
    else:
        (run / "params.yaml").unlink()
    runner = Processes(tmp_path, cwd=REPO)
    try:
        result = runner.run(["rosrun", "moving_cube_training", "evaluate.py", "--qtable", str(run)], timeout=120)
    finally:
        runner.close()
    assert result.returncode == 2, result.stderr
    assert one_line(result.stderr, expected).startswith("evaluate.py: cannot read the trained run")


# -- the env over ROS ----------------------------------------------------------------------------

def env_over_ros(master: RosMaster, tmp_path: Path, env_id: str, timeout: float = 3.0) -> subprocess.CompletedProcess:
    """gymnasium.make(env_id, backend="ros") in a fresh process without rospy.init_node, as a user writes it."""
    script = tmp_path / "make_env.py"
    script.write_text(f"""import gymnasium, hopper_training, moving_cube_training
env = gymnasium.make({env_id!r}, backend="ros", ros_timeout={timeout})
env.reset(seed=0)
env.step(0)
env.close()
print("stepped")
""")
    return master.run([sys.executable, str(script)], timeout=60)


def test_env_over_ros_with_no_master_says_so_at_once(tmp_path):
    runner = Processes(tmp_path, cwd=REPO, ROS_MASTER_URI="http://127.0.0.1:1")
    script = tmp_path / "make_env.py"
    script.write_text("import gymnasium, moving_cube_training\n"
                      "gymnasium.make('MovingCubeOneDiskWalk-v0', backend='ros')\n")
    started = time.monotonic()
    try:
        result = runner.run([sys.executable, str(script)], timeout=60)
    finally:
        runner.close()
    assert result.returncode == 1 and time.monotonic() - started < 20
    one_line(result.stderr.replace("Traceback", "traceback"),
             "no ROS master at http://127.0.0.1:1 (ROS_MASTER_URI)")


def test_env_over_ros_with_no_sim_names_the_service_and_the_launch(master, tmp_path):
    started = time.monotonic()
    result = env_over_ros(master, tmp_path, "Monoped-v0", timeout=2.0)
    assert result.returncode == 1 and time.monotonic() - started < 30
    line = one_line(result.stderr.replace("Traceback", "traceback"), "service /gazebo/pause_physics is not available")
    assert "roslaunch pybullet_sim hopper_sim.launch" in line


def test_env_over_ros_without_init_node_works_and_leaves_a_running_sim_running(master, tmp_path):
    master.start(["roslaunch", "pybullet_sim", "cube_sim.launch", "robot_state_publisher:=false", "paused:=false"],
                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    result = env_over_ros(master, tmp_path, "MovingCubeOneDiskWalk-v0", timeout=10.0)
    assert result.returncode == 0 and result.stdout.strip().endswith("stepped"), result.stderr[-3000:]
    physics = master.run(["rosservice", "call", "/gazebo/get_physics_properties"], timeout=30).stdout
    assert "pause: False" in physics, physics
    master.close()


def test_env_of_another_robot_is_refused_with_the_reason(master, tmp_path):
    master.start(["roslaunch", "pybullet_sim", "cube_sim.launch", "robot_state_publisher:=false"],
                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    result = env_over_ros(master, tmp_path, "Monoped-v0", timeout=10.0)
    assert result.returncode == 1
    line = one_line(result.stderr.replace("Traceback", "traceback"),
                    "the sim node /pybullet_sim simulates /moving_cube, not /monoped")
    assert "roslaunch pybullet_sim hopper_sim.launch" in line
    master.close()


# -- processes that die, freeze or are stopped during training ------------------------------------

def start_cube_training(master: Processes, tmp_path: Path, log: Path, *args: str, **changes) -> subprocess.Popen:
    """A long cube training (angle limits out of reach: every episode lasts nsteps); `args`: launch arguments."""
    config = cube_config(tmp_path / "config.yaml", **{"nepisodes": 400, "nsteps": 50, "max_pitch_angle": 10.0,
                                                       "max_yaw_angle": 10.0, **changes})
    with open(log, "w") as out:
        return master.start([*CUBE_TRAINING, f"config:={config}", f"results_dir:={tmp_path / 'results'}", *args],
                            stdout=out, stderr=subprocess.STDOUT)


def as_ws_run(tmp_path: Path) -> tuple[str, Processes]:
    """(master URI, processes) as ./ws run has them: ROS on loopback, a free port, no master yet (roslaunch
    starts it)."""
    uri = f"http://127.0.0.1:{free_port()}"
    return uri, Processes(tmp_path, cwd=REPO, ROS_MASTER_URI=uri, ROS_HOSTNAME="127.0.0.1", ROS_IP="127.0.0.1")


def logged_episode(log: Path, episode: int):
    return lambda: f"EP: {episode} " in log.read_text()


def test_ctrl_c_stops_with_a_checkpoint_and_an_incomplete_summary_then_resumes(master, tmp_path):
    log = tmp_path / "run.log"
    launch = start_cube_training(master, tmp_path, log)
    wait_for(logged_episode(log, 15), 120, "episode 15")
    launch.send_signal(signal.SIGINT)  # Ctrl-C reaches roslaunch, which stops every node with SIGINT
    assert launch.wait(60) == INTERRUPTED, log.read_text()[-3000:]
    output = log.read_text()
    line = one_line(output, "training interrupted after episode")
    saved = int(re.search(r"after episode (\d+):", line).group(1))
    assert saved >= 15
    results = tmp_path / "results"
    summary = json.loads((results / "moving_cube" / "latest" / "summary.json").read_text())
    assert (summary["completed"], summary["stopped"], summary["episodes"]) == (False, "interrupted", saved)
    assert json.loads((results / "moving_cube" / "latest" / "qtable.json").read_text())["episode"] == saved
    assert episodes(results) == list(range(1, saved + 1)), "the interrupted episode is not logged"

    result = master.run([*CUBE_TRAINING, f"config:={tmp_path / 'config.yaml'}", f"results_dir:={results}",
                         "resume:=true", f"nepisodes:={saved + 5}"], timeout=180)
    assert result.returncode == 0, (result.stdout + result.stderr)[-3000:]
    assert episodes(results) == list(range(1, saved + 6))
    assert json.loads((results / "moving_cube" / "latest" / "summary.json").read_text())["completed"] is True


def interrupt_while_logging(master: RosMaster, logging: Path) -> int | None:
    """Start logging_node.py, SIGINT it once it logs; its exit code, or None if it did not end within 20 s."""
    node = master.start([sys.executable, str(PROGRAMS / "logging_node.py"), str(logging)],
                        stdout=subprocess.DEVNULL)
    wait_for(lambda: logging.exists() or node.poll() is not None, 30, "logging_node.py's first log line")
    assert node.poll() is None, f"logging_node.py ended (exit {node.returncode}) before it logged"
    node.send_signal(signal.SIGINT)
    try:
        return node.wait(20)
    except subprocess.TimeoutExpired:
        node.kill()
        node.wait()
        return None


def test_ctrl_c_in_the_middle_of_a_log_line_ends_the_node(master, tmp_path):
    """The training node's stop on SIGINT, landing while a log line holds rospy's locks: when the handler ran
    rospy's shutdown itself, 14 of 20 such nodes waited on their own lock until killed."""
    codes = [interrupt_while_logging(master, tmp_path / f"logging{attempt}") for attempt in range(5)]
    assert codes == [INTERRUPTED] * 5, f"exit codes of 5 nodes (None: still running 20 s after SIGINT): {codes}"


def sim_time(master: RosMaster) -> float:
    """The sim's time from /gazebo/get_world_properties; 0 while the service is not up yet, or when the call has
    not answered within 10 s (then the next poll asks again: once in some ten clean-clone runs one rosservice
    process hung for 30 s, and that ended the test)."""
    try:
        result = master.run(["rosservice", "call", "/gazebo/get_world_properties"], timeout=10)
    except AssertionError:  # run()'s "did not finish within 10 s", the call stopped
        return 0.0
    return float(yaml.safe_load(result.stdout)["sim_time"]) if result.returncode == 0 else 0.0


def test_ctrl_c_on_a_sim_running_as_fast_as_it_can_ends_it_at_once(master, tmp_path):
    """SIGINT while the sim node steps flat out, holding its lock nearly all the time: with rospy's own handler
    (its shutdown hook takes that lock) roslaunch escalated to SIGTERM and SIGKILL, 17 s, 6 times in 6."""
    log = tmp_path / "sim.log"
    with open(log, "w") as out:
        launch = master.start(["roslaunch", "pybullet_sim", "cube_sim.launch", "paused:=false", "real_time_factor:=0",
                               "robot_state_publisher:=false"], stdout=out, stderr=subprocess.STDOUT)
    try:
        wait_for(lambda: sim_time(master) > 0.5, 90,
                 f"the running cube sim's time (/gazebo/get_world_properties) > 0.5 s (its log: {log})")
        launch.send_signal(signal.SIGINT)
        assert launch.wait(60) == 0, log.read_text()[-3000:]
    finally:
        if launch.poll() is None:  # the test failed: its launch goes, and the failure is the test's alone
            stop(launch)
    output = log.read_text()
    assert "escalating" not in output and "Traceback" not in output, output[-3000:]


def test_the_master_killed_during_training_does_not_stop_it(master, tmp_path):
    """Nodes talk peer to peer once connected: the run finishes and writes everything."""
    log = tmp_path / "run.log"
    launch = start_cube_training(master, tmp_path, log, nepisodes=30)
    wait_for(logged_episode(log, 5), 120, "episode 5")
    os.kill(master.master_pid, signal.SIGKILL)
    assert launch.wait(180) == 0, log.read_text()[-3000:]
    one_line(log.read_text(), "Training complete: 30 episodes")
    assert episodes(tmp_path / "results") == list(range(1, 31))


def test_sigkill_of_the_sim_stops_training_with_one_line_and_a_checkpoint(master, tmp_path):
    log = tmp_path / "run.log"
    launch = start_cube_training(master, tmp_path, log)
    wait_for(logged_episode(log, 12), 120, "episode 12")
    os.kill(node_pid(master, "/pybullet_sim"), signal.SIGKILL)
    assert launch.wait(60) == 128 + signal.SIGKILL, "the sim's death ends the launch with its code"
    output = log.read_text()
    one_line(output, "continue with resume:=true")  # "training interrupted" or "training stopped"
    results = tmp_path / "results"
    checkpoint = json.loads((results / "moving_cube" / "latest" / "qtable.json").read_text())
    assert episodes(results)[:checkpoint["episode"]] == list(range(1, checkpoint["episode"] + 1))
    assert checkpoint["episode"] >= 10


def test_a_frozen_sim_stops_training_within_the_timeout(master, tmp_path):
    """SIGSTOP on the sim: the step call has a deadline; the run is saved and the node says why."""
    log = tmp_path / "run.log"
    config = cube_config(tmp_path / "config.yaml", nepisodes=400, nsteps=50, max_pitch_angle=10.0, max_yaw_angle=10.0)
    master.params.setParam("/movingcube_gym/timeout", 2.0)
    with open(log, "w") as out:
        launch = master.start([*CUBE_TRAINING, f"config:={config}", f"results_dir:={tmp_path / 'results'}"],
                              stdout=out, stderr=subprocess.STDOUT)
    wait_for(logged_episode(log, 12), 120, "episode 12")
    sim = node_pid(master, "/pybullet_sim")
    os.kill(sim, signal.SIGSTOP)
    try:
        wait_for(lambda: "did not answer within" in log.read_text(), 30, "the training node giving up on the sim")
    finally:
        os.kill(sim, signal.SIGCONT)
    assert launch.wait(60) == 1
    line = one_line(log.read_text(), "did not answer within 2.0 s")
    assert "[FATAL]" in line and "continue with resume:=true" in line
    summary = json.loads((tmp_path / "results" / "moving_cube" / "latest" / "summary.json").read_text())
    assert summary["completed"] is False and summary["stopped"].startswith("error: service")
    assert summary["episodes"] == episodes(tmp_path / "results")[-1]


CHANGE_THE_SIM = {
    "time_step": """import rospy
from gazebo_msgs.srv import GetPhysicsProperties, SetPhysicsProperties
current = rospy.ServiceProxy("/gazebo/get_physics_properties", GetPhysicsProperties)()
answer = rospy.ServiceProxy("/gazebo/set_physics_properties", SetPhysicsProperties)(
    0.01, current.max_update_rate, current.gravity, current.ode_config)
assert answer.success, answer.status_message
""",
    "reset_simulation": """import rospy
from std_srvs.srv import Empty
for _ in range(3):
    rospy.ServiceProxy("/gazebo/reset_simulation", Empty)()
"""}


@pytest.mark.parametrize("change, expected", [
    ("time_step", "its time step is now 0.01 s, this env started with 0.001 s"),
    ("reset_simulation", "its time went back from"),
])
def test_a_sim_changed_from_outside_stops_training_with_one_line_then_resumes(master, tmp_path, change, expected):
    """Another node sets the sim's time step, or resets it, mid-run: each step would cover another span
    of sim time (or time goes back) and the run would go on regardless. The next step says so."""
    log = tmp_path / "run.log"
    launch = start_cube_training(master, tmp_path, log, nepisodes=400)
    wait_for(logged_episode(log, 12), 120, "episode 12")
    script = tmp_path / "change.py"
    script.write_text(CHANGE_THE_SIM[change])
    changed = master.run([sys.executable, str(script)], timeout=60)
    assert changed.returncode == 0, changed.stderr[-3000:]
    assert launch.wait(60) == 1, log.read_text()[-3000:]
    line = one_line(log.read_text(), "the sim was changed from outside")
    assert "[FATAL]" in line and expected in line and "continue with resume:=true" in line, line
    results = tmp_path / "results"
    summary = json.loads((results / "moving_cube" / "latest" / "summary.json").read_text())
    assert summary["completed"] is False and "changed from outside" in summary["stopped"]
    saved = json.loads((results / "moving_cube" / "latest" / "qtable.json").read_text())["episode"]
    assert saved == summary["episodes"] >= 12 and episodes(results) == list(range(1, saved + 1))
    resumed = master.run([*CUBE_TRAINING, f"config:={tmp_path / 'config.yaml'}", f"results_dir:={results}",
                          "resume:=true", f"nepisodes:={saved + 3}"], timeout=180)
    assert resumed.returncode == 0, (resumed.stdout + resumed.stderr)[-3000:]
    assert episodes(results) == list(range(1, saved + 4))


def test_sigkill_of_the_trainer_between_checkpoints_then_resume(master, tmp_path):
    log = tmp_path / "run.log"
    launch = start_cube_training(master, tmp_path, log, nepisodes=40)
    results = tmp_path / "results"
    qtable = results / "moving_cube" / "latest" / "qtable.json"

    wait_for(qtable.exists, 120, "the run's first checkpoint")
    trainer = node_pid(master, "/movingcube_gym")

    def frozen_between_checkpoints():
        """The trainer frozen (SIGSTOP) while episodes.csv holds more than its checkpoint at episode >= 10, else
        let go on. Killed as it is found so: a kill after the check had raced the next checkpoint (the cube's
        episodes are short; `rosnode info` in between took long enough for it on a loaded machine)."""
        os.kill(trainer, signal.SIGSTOP)
        wait_for(lambda: stat_fields(trainer)[0] == "T", 10, f"the trainer (pid {trainer}) stopped by SIGSTOP")
        if 10 <= json.loads(qtable.read_text())["episode"] < len(episodes(results)):
            return True
        os.kill(trainer, signal.SIGCONT)
        return False
    wait_for(frozen_between_checkpoints, 120, "a checkpoint at episode >= 10 followed by another episode")
    os.kill(trainer, signal.SIGKILL)
    assert launch.wait(60) == 128 + signal.SIGKILL
    saved = json.loads(qtable.read_text())["episode"]
    logged = episodes(results)
    assert len(logged) > saved and not (results / "moving_cube" / "latest" / "summary.json").exists()
    checkpointed = (results / "moving_cube" / "latest" / "episodes.csv").read_text().split("\n")[:saved + 1]

    result = master.run([*CUBE_TRAINING, f"config:={tmp_path / 'config.yaml'}", f"results_dir:={results}",
                         "resume:=true"], timeout=180)
    output = result.stdout + result.stderr
    assert result.returncode == 0, output[-3000:]
    one_line(output, f"after episode {saved} (epsilon")
    assert episodes(results) == list(range(1, 41)), "no episode lost or repeated"
    assert (results / "moving_cube" / "latest" / "episodes.csv").read_text().split("\n")[:saved + 1] == checkpointed


def test_sigkill_of_the_launcher_leaves_no_process_of_the_run(tmp_path):
    """kill -9 of what ./ws run starts (roslaunch_checked.py, which starts the master as ./ws run's does):
    the master, rosout, the sim node and the trainer all end with it (roslaunch's nodes run in sessions
    of their own and used to be reparented to PID 1 and left running)."""
    uri, runner = as_ws_run(tmp_path)
    log = tmp_path / "run.log"
    try:
        launcher = start_cube_training(runner, tmp_path, log)
        wait_for(logged_episode(log, 2), 120, "episode 2")
        names = {Path(f"/proc/{pid}/comm").read_text().strip() for pid in processes_using(uri)}
        assert {"rosmaster", "rosout"} <= names and len(names) >= 4, names
        launcher.kill()
        assert launcher.wait(10) == -signal.SIGKILL
        wait_for(lambda: processes_using(uri) == [], 20, "the end of every process of the killed launch")
    finally:
        runner.close()
        for pid in processes_using(uri):  # what the launch left running, had the test failed
            os.kill(pid, signal.SIGKILL)


def worker_sims(trainer: int) -> list[int]:
    """The sim nodes of a vector trainer's workers."""
    sims = []
    for pid in descendants(trainer):
        try:
            if b"sim_node.py" in Path(f"/proc/{pid}/cmdline").read_bytes():
                sims.append(pid)
        except OSError:
            continue
    return sims


def start_vector_training(master: RosMaster, tmp_path: Path, log: Path) -> subprocess.Popen:
    config = cube_config(tmp_path / "config.yaml", nepisodes=400, nsteps=50, max_pitch_angle=10.0, max_yaw_angle=10.0)
    with open(log, "w") as out:
        return master.start([*CUBE_TRAINING, f"config:={config}", f"results_dir:={tmp_path / 'results'}", "envs:=2"],
                            stdout=out, stderr=subprocess.STDOUT)


@pytest.mark.parametrize("fault", [signal.SIGKILL, signal.SIGSTOP], ids=["killed", "frozen"])
def test_a_killed_or_frozen_worker_sim_stops_training_with_one_line_naming_its_log(master, tmp_path, fault):
    """envs:=2 and a worker's sim node killed, or frozen (SIGSTOP: the worker's step call times out): one
    FATAL line naming the worker and the sim's log, with no traceback and no hint to start a launch file
    (a worker starts its own sim); the run is saved."""
    log = tmp_path / "run.log"
    launch = start_vector_training(master, tmp_path, log)
    wait_for(logged_episode(log, 12), 180, "episode 12")
    trainer = node_pid(master, "/movingcube_gym")
    sims = wait_for(lambda: worker_sims(trainer), 10, "the workers' sim nodes")
    os.kill(sims[0], fault)
    assert launch.wait(120) == 1, log.read_text()[-3000:]
    line = one_line(log.read_text(), "training stopped: worker")
    assert "[FATAL]" in line and "roslaunch pybullet_sim" not in line and "continue with resume:=true" in line, line
    if fault == signal.SIGKILL:
        assert "is gone or frozen: its log is" in line, line
        sim_log = Path(re.search(r"its log is (\S+sim_node\.log)", line).group(1))
    else:
        assert "did not answer within 10.0 s: the sim node is frozen or overloaded" in line, line
        sim_log = Path(re.search(r"logs \(if any\) are kept in (\S+)\.", line).group(1)) / "sim_node.log"
    assert sim_log.is_file(), f"the log the line names is kept: {sim_log}"
    shutil.rmtree(sim_log.parent.parent)  # the failed workers' folder, kept for the user
    wait_for(lambda: not any(Path(f"/proc/{pid}").exists() for pid in [trainer, *sims]), 30,
             "the end of the trainer and its workers' sim nodes")
    summary = json.loads((tmp_path / "results" / "moving_cube" / "latest" / "summary.json").read_text())
    assert summary["completed"] is False and summary["episodes"] == episodes(tmp_path / "results")[-1] >= 12


def test_ctrl_c_while_the_workers_start_ends_the_run_with_no_traceback(tmp_path):
    """Ctrl-C (SIGINT to the launch's process group, as a terminal sends it) while the envs:=2 workers start
    their masters and sims, the launch having started its own master as ./ws run's does: the master goes
    first and refuses the node's calls. Exit 130, no traceback, no process left."""
    uri, runner = as_ws_run(tmp_path)
    log = tmp_path / "run.log"
    config = cube_config(tmp_path / "config.yaml", nepisodes=400, nsteps=50)
    folders_before = set(Path(tempfile.gettempdir()).glob("robot_rl-workers-*"))
    try:
        with open(log, "w") as out:
            launch = runner.start([*CUBE_TRAINING, f"config:={config}", f"results_dir:={tmp_path / 'results'}",
                                   "envs:=2"], stdout=out, stderr=subprocess.STDOUT)
        wait_for(lambda: "Starting 2 envs" in log.read_text(), 120, "the training node starting its workers")
        os.killpg(launch.pid, signal.SIGINT)
        assert launch.wait(60) == INTERRUPTED, log.read_text()[-3000:]
        wait_for(lambda: processes_using(uri) == [], 30, "the end of every process of the launch")
    finally:
        runner.close()
        for pid in processes_using(uri):  # what the launch left running, had the test failed
            os.kill(pid, signal.SIGKILL)
    output = log.read_text()
    assert "Traceback" not in output and "ConnectionRefusedError" not in output, output[-3000:]
    assert set(Path(tempfile.gettempdir()).glob("robot_rl-workers-*")) <= folders_before, "a workers' folder is left"


def test_results_dir_that_is_a_file_gives_one_line(master, tmp_path):
    not_a_dir = tmp_path / "results"
    not_a_dir.write_text("a file")
    config = cube_config(tmp_path / "config.yaml", nepisodes=2, nsteps=10)
    result = master.run([*CUBE_TRAINING, f"config:={config}", f"results_dir:={not_a_dir}"], timeout=120)
    assert result.returncode == 1
    assert str(not_a_dir) in one_line(result.stdout + result.stderr, "cannot write the results")
    assert not_a_dir.read_text() == "a file"


@pytest.mark.parametrize("results_dir", ["runs", "~/runs"])
def test_a_relative_or_home_results_dir_is_where_the_command_ran(master, tmp_path, results_dir):
    """roslaunch runs nodes in ROS_HOME: `results_dir:=runs` used to land in ~/.ros/runs, and `~` to be a
    folder named "~" there."""
    here, home = tmp_path / "here", tmp_path / "home"
    here.mkdir()
    home.mkdir()
    runner = Processes(tmp_path / "ros_here", cwd=here, ROS_MASTER_URI=master.uri, ROS_HOSTNAME="127.0.0.1",
                       ROS_IP="127.0.0.1", HOME=str(home), PWD=str(here))
    config = cube_config(tmp_path / "config.yaml", nepisodes=2, nsteps=10)
    try:
        result = runner.run([*CUBE_TRAINING, f"config:={config}", f"results_dir:={results_dir}"], timeout=120)
    finally:
        runner.close()
    output = result.stdout + result.stderr
    assert result.returncode == 0, output[-3000:]
    expected = (here if results_dir == "runs" else home) / "runs" / "moving_cube"
    assert str(expected) in one_line(output, "Results go to ")
    assert episodes(expected.parent) == [1, 2]
    assert not (tmp_path / "ros_here" / "runs").exists() and not list(tmp_path.rglob("~"))


def test_disk_full_gives_one_line_and_keeps_the_last_checkpoint(master, tmp_path):
    """The results on a 256 KiB tmpfs: a long run fills it; the run stops with one line naming the file,
    and its last checkpoint still loads."""
    disk = tmp_path / "small_disk"
    disk.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(disk)]).returncode != 0:
        pytest.skip("mounting a tmpfs needs root")
    try:
        config = cube_config(tmp_path / "config.yaml", nepisodes=5000, nsteps=30)
        result = master.run([*CUBE_TRAINING, f"config:={config}", f"results_dir:={disk}"], timeout=600)
        output = result.stdout + result.stderr
        assert result.returncode == 1, output[-3000:]
        assert "No space left on device" in one_line(output, f"cannot write the results: {disk}")
        run = disk / "moving_cube" / "latest"
        checkpoint = json.loads((run / "qtable.json").read_text())
        assert checkpoint["episode"] >= 10 and checkpoint["episode"] <= len(episodes(disk))
    finally:  # lazily: detached now even if an interrupted run still holds a file on it
        subprocess.run(["umount", "--lazy", str(disk)], check=True)


def test_two_runs_in_one_checkout_at_once(tmp_path):
    """Two trainings side by side, each on its own master, into the same results folder."""
    masters = [RosMaster(tmp_path / f"ros{i}", cwd=REPO) for i in range(2)]
    config = cube_config(tmp_path / "config.yaml", nepisodes=5, nsteps=30)
    try:
        launches = [m.start([*CUBE_TRAINING, f"config:={config}", f"results_dir:={tmp_path / 'results'}"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for m in masters]
        assert [launch.wait(180) for launch in launches] == [0, 0]
        assert all(m.leftovers() == [] for m in masters)
    finally:
        for m in masters:
            m.close()
    runs = [p for p in (tmp_path / "results" / "moving_cube").iterdir() if p.name != "latest"]
    assert len(runs) == 2
    assert all(json.loads((run / "summary.json").read_text())["completed"] for run in runs)


def test_every_socket_of_a_training_run_is_on_loopback_but_xmlrpcpps(tmp_path):
    """ROS_IP and ROS_HOSTNAME as ./ws sets them; roslaunch starts the master and rosout itself, as with
    ./ws run. Every listening socket is on 127.0.0.1, the C++ nodes' TCPROS servers too (roscpp binds
    them to loopback when ROS_IP is 127.*), but for the XML-RPC servers of the C++ nodes (rosout,
    robot_state_publisher): xmlrpcpp binds INADDR_ANY whatever ROS_IP says (ros_comm
    utilities/xmlrpcpp/src/XmlRpcSocket.cpp); roscpp still refuses TCPROS peers off this host."""
    uri, runner = as_ws_run(tmp_path)
    log = tmp_path / "run.log"
    try:
        start_cube_training(runner, tmp_path, log, "robot_state_publisher:=true")
        wait_for(logged_episode(log, 2), 120, "episode 2")
        listening = _listening_sockets()
        pids = processes_using(uri)
        names = {pid: Path(f"/proc/{pid}/comm").read_text().strip() for pid in pids}
        assert {"rosmaster", "rosout", "robot_state_pub"} <= set(names.values()), names
        master = rosgraph.Master("/pytest", master_uri=uri)
        xmlrpc_ports = {int(master.lookupNode(node).rstrip("/").rsplit(":", 1)[1])
                        for node in ("/rosout", "/robot_state_publisher")}
        exceptions = []
        for pid in pids:
            for inode in _socket_inodes(pid):
                if inode in listening and not listening[inode].startswith("127.0.0.1:"):
                    assert names[pid] in ("rosout", "robot_state_pub"), f"{names[pid]} listens on {listening[inode]}"
                    assert int(listening[inode].rsplit(":", 1)[1]) in xmlrpc_ports, listening[inode]
                    exceptions.append(names[pid])
        assert sorted(exceptions) == ["robot_state_pub", "rosout"], exceptions
    finally:
        runner.close()
    assert processes_using(uri) == []


def _listening_sockets() -> dict[int, str]:
    """inode -> "address:port" of every listening TCP socket (IPv4 and IPv6) of this machine."""
    sockets = {}
    for table, width in (("/proc/net/tcp", 8), ("/proc/net/tcp6", 32)):
        for line in Path(table).read_text().splitlines()[1:]:
            fields = line.split()
            if fields[3] == "0A":  # LISTEN
                address, port = fields[1].split(":")
                if width == 8:
                    host = ".".join(str(int(address[i:i + 2], 16)) for i in (6, 4, 2, 0))
                else:
                    host = "::1" if address == "0" * 24 + "01000000" else f"[{address}]"
                sockets[int(fields[9])] = f"{host}:{int(port, 16)}"
    return sockets


def _socket_inodes(pid: int) -> list[int]:
    inodes = []
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.append(int(target[8:-1]))
    return inodes


MEMORY_SCRIPT = PROGRAMS / "memory_client.py"


def test_memory_stays_flat_over_10000_resets_and_100000_lockstep_steps(master, tmp_path):
    master.start(["roslaunch", "pybullet_sim", "cube_sim.launch", "robot_state_publisher:=false"],
                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wait_for(lambda: "/pybullet_sim/step" in str(master.params.getSystemState()[2]), 60, "the cube sim")
    result = master.run([sys.executable, str(MEMORY_SCRIPT), str(node_pid(master, "/pybullet_sim"))], timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    growth = json.loads(result.stdout.strip().splitlines()[-1])
    assert growth["resets"] == 10000 and growth["steps"] == 100000
    assert growth["sim_kib"] < 8 * 1024 and growth["client_kib"] < 8 * 1024, growth
    master.close()
