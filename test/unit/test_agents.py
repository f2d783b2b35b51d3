"""The agent registry (robot_rl.agents): names, default configs, results folders, checkpoints, the
launch files' list of agents and the `needs-deep` question ./ws asks. No ROS master."""
import dataclasses
import re
import subprocess
import sys
from pathlib import Path

import pytest

from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from robot_rl import (
    AGENTS,
    DEEP_CHECKPOINT,
    QTABLE_CHECKPOINT,
    ParamError,
    Params,
    agent_of,
    checkpoint_of,
    find_agent,
    find_task,
)
from robot_rl.agents.registry import main

pytestmark = pytest.mark.deep  # needs torch and Stable-Baselines3 (requirements-deep.txt)

ROOT = Path(__file__).resolve().parents[2]
LAUNCH_FILES = ["robot_rl/launch/train.launch", "moving_cube_training/launch/main.launch",
                "hopper_training/launch/main.launch"]


def test_find_agent_and_the_unknown_agent_message():
    assert [find_agent(name).name for name in ("qlearn", "dqn", "ppo", "sac")] == ["qlearn", "dqn", "ppo", "sac"]
    assert list(AGENTS) == ["qlearn", "dqn", "ppo", "sac", "bc_dagger", "ppo_finetune", "rllib_ppo"]
    with pytest.raises(ParamError, match=r"^unknown agent 'x' \(known: qlearn, dqn, ppo, sac, bc_dagger, ppo_finetune, "
                                         r"rllib_ppo\)$"):
        find_agent("x")


@pytest.mark.parametrize("name", list(AGENTS))
def test_every_agent_has_a_loadable_default_config(name):
    agent = find_agent(name)
    params = agent.load_params()
    if agent.params is None:
        assert params is None and agent.config_path is None
        assert agent.load_params(Path("/nonexistent.yaml")) is None, "the task's params: no file of its own read"
    else:
        assert isinstance(params, Params) and agent.config_path.name == f"{name}.yaml"
        assert agent.load_params_from(params.to_mapping(), "test") == params


def test_a_task_s_own_agent_config_is_picked_where_there_is_one(tmp_path):
    from hopper_training import TASKS as HOPPER_TASKS
    hop_in_place = find_task(HOPPER_TASKS, "hop_in_place")
    agent = find_agent("dqn")
    own = agent.task_config_path(ONE_DISK_WALK)
    assert own.parent == ONE_DISK_WALK.config_path.parent / "agents" and own.name == "one_disk_walk.dqn.yaml"
    assert agent.config_for(ONE_DISK_WALK) == own and own.is_file(), "the cube's tuned DQN config"
    assert agent.load_params(own) != agent.load_params(), "tuned: not the general file's values"
    assert find_agent("sac").config_for(hop_in_place) == find_agent("sac").config_path, \
        "no file of the task's own for this agent: the agent's general one"
    no_file = dataclasses.replace(ONE_DISK_WALK, name="no_such_task")
    assert agent.config_for(no_file) == agent.config_path, "no file of the task's own: the agent's general one"
    assert find_agent("qlearn").config_for(ONE_DISK_WALK) is None and \
        find_agent("qlearn").task_config_path(ONE_DISK_WALK) is None, "tabular's params are the task's"


def test_every_task_s_agent_config_names_a_task_and_an_agent_and_loads():
    from hopper_training import TASKS as HOPPER_TASKS
    from moving_cube_training import TASKS as CUBE_TASKS
    for package, tasks in (("moving_cube_training", CUBE_TASKS), ("hopper_training", HOPPER_TASKS)):
        for path in sorted((ROOT / package / "config" / "agents").glob("*")):
            task_name, _, rest = path.name.partition(".")
            agent_name, _, suffix = rest.partition(".")
            assert suffix == "yaml" and task_name in [t.name for t in tasks], f"{path}: not <task>.<agent>.yaml"
            assert isinstance(find_agent(agent_name).load_params(path), Params)
            assert "./ws sweep" in path.read_text(), f"{path}: names the sweep that chose it"


def test_the_from_scratch_agent_configs_load_and_the_normalised_one_differs_only_by_normalising():
    folder = ROOT / "hopper_training" / "config" / "end_to_end_scratch"
    plain = find_agent("ppo").load_params(folder / "ppo.yaml")
    normalised = find_agent("ppo").load_params(folder / "ppo_normalised.yaml")
    assert find_agent("rllib_ppo").load_params(folder / "rllib_ppo.yaml") is not None
    assert not plain.normalise_observations and normalised.normalise_observations
    assert dataclasses.replace(normalised, normalise_observations=False) == plain, "Track B's runs compare one change"


def test_results_folders_and_checkpoints():
    assert {name: spec.results_name(ONE_DISK_WALK) for name, spec in AGENTS.items()} == \
        {"qlearn": "moving_cube", "dqn": "moving_cube-dqn", "ppo": "moving_cube-ppo", "sac": "moving_cube-sac",
         "bc_dagger": "moving_cube-bc_dagger",
         "ppo_finetune": "moving_cube-ppo_finetune", "rllib_ppo": "moving_cube-rllib_ppo"}
    assert {name: spec.checkpoint_name for name, spec in AGENTS.items()} == \
        {"qlearn": QTABLE_CHECKPOINT, "dqn": DEEP_CHECKPOINT, "ppo": DEEP_CHECKPOINT, "sac": DEEP_CHECKPOINT,
         "bc_dagger": DEEP_CHECKPOINT, "ppo_finetune": DEEP_CHECKPOINT, "rllib_ppo": DEEP_CHECKPOINT}
    assert {name: spec.needs_deep for name, spec in AGENTS.items()} == \
        {"qlearn": False, "dqn": True, "ppo": True, "sac": True, "bc_dagger": True, "ppo_finetune": True,
         "rllib_ppo": True}


def test_a_run_folder_s_checkpoint_and_agent(tmp_path):
    assert checkpoint_of(tmp_path) == tmp_path / QTABLE_CHECKPOINT, "nothing there: the tabular checkpoint"
    (tmp_path / DEEP_CHECKPOINT).write_text("{}")
    assert checkpoint_of(tmp_path) == tmp_path / DEEP_CHECKPOINT
    (tmp_path / QTABLE_CHECKPOINT).write_text("{}")
    assert checkpoint_of(tmp_path) == tmp_path / QTABLE_CHECKPOINT, "a Q-table first"
    assert agent_of({"task": "MovingCubeOneDiskWalk-v0"}) is AGENTS["qlearn"]
    assert agent_of({"agent": "ppo"}) is AGENTS["ppo"]
    with pytest.raises(ParamError, match="unknown agent 'a2c'"):
        agent_of({"agent": "a2c"})


@pytest.mark.parametrize("path", LAUNCH_FILES)
def test_the_launch_files_list_every_agent(path):
    doc = re.search(r'<arg name="agent"[^>]* doc="([^"]*)"', (ROOT / path).read_text())[1]
    assert all(re.search(rf"\b{name}\b", doc) for name in AGENTS), doc
    assert all(spec.description.split(", ")[0] in doc for spec in AGENTS.values()), doc


def test_needs_deep_answers_by_exit_code():
    assert [main(["needs-deep", name]) for name in ("qlearn", "dqn", "ppo", "x")] == [1, 0, 0, 1]
    assert main([]) == 2
    done = subprocess.run([sys.executable, "-c", "import sys, robot_rl.agents.registry; "
                           "sys.exit(robot_rl.agents.registry.main(['needs-deep', 'dqn']) or 'torch' in sys.modules)"])
    assert done.returncode == 0, "the registry answers without importing torch"


def test_an_agent_config_with_an_unknown_key_is_refused_naming_it_and_the_file(tmp_path):
    config = tmp_path / "dqn.yaml"
    config.write_text(AGENTS["dqn"].config_path.read_text() + "learnig_rate: 0.1\n")
    with pytest.raises(ParamError, match=rf"^{re.escape(str(config))}: unknown parameter 'learnig_rate' \(known: "):
        AGENTS["dqn"].load_params(config)
