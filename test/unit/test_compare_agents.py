"""compare_agents.py's choices: the task (--task), the agents that can act in its action space, and the table
naming each agent's params file. No ROS master; the deep agents' packages (torch) are imported."""
import pytest

import workspace_tools.compare as compare_agents
from hopper_training.envs.hop_in_place import HOP_IN_PLACE as HOP_LEVEL
from hopper_training.envs.stay_up import STAY_UP
from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from robot_rl import ParamError

pytestmark = pytest.mark.deep  # needs torch and Stable-Baselines3 (requirements-deep.txt)


def test_the_task_is_the_robot_s_first_unless_named():
    assert compare_agents._task("cube", None) is ONE_DISK_WALK
    assert compare_agents._task("hopper", None) is STAY_UP
    assert compare_agents._task("hopper", "hop_in_place") is HOP_LEVEL
    with pytest.raises(ParamError, match=r"^unknown task 'fly' \(known: "):
        compare_agents._task("hopper", "fly")


def test_only_the_agents_that_can_act_in_the_task_s_action_space_are_compared():
    assert [agent.name for agent in compare_agents._agents(ONE_DISK_WALK)] == ["qlearn", "dqn", "ppo"]  # Discrete(5)
    assert [agent.name for agent in compare_agents._agents(HOP_LEVEL)] == ["qlearn", "dqn", "ppo"]  # Discrete(6)


def test_the_table_names_each_agent_s_params_file(tmp_path):
    def run(agent, config, greedy):
        return {"agent": agent, "agent_config": config, "seed": 0, "env_steps": 100, "episodes": 3,
                "wall_time_s": 2.0, "env_steps_per_s": 50.0, "greedy": {"success_rate": greedy},
                "random": {"success_rate": 0.0}, "curve_steps": [50, 100], "curve": [0.0, 1.0]}
    report = {"task": "MovingCubeOneDiskWalk-v0", "running_step": 0.06, "qlearn_nepisodes": 200, "seeds": [0],
              "eval_episodes": 20, "eval_seed": 0, "machine": "test", "date": "today", "headline_metric": "success",
              "greedy_metric": "success_rate", "agents": ["qlearn", "dqn"],
              "runs": [run("qlearn", None, 1.0), run("dqn", "/x/config/agents/one_disk_walk.dqn.yaml", 0.5)]}
    compare_agents._write_table(report, tmp_path / "comparison.md")
    rows = (tmp_path / "comparison.md").read_text().splitlines()[-2:]
    assert rows[0].startswith("| qlearn (the task config) | 100 | 1.00 |")
    assert rows[1].startswith("| dqn (one_disk_walk.dqn.yaml) | 100 | 0.50 |")
