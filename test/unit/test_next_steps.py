"""What the training node says around a run (robot_rl.runs.next_steps): the start line's episode budget and the
end block's "train further" hint, true for an agent whose params count its episodes (bc_dagger) as for the rest."""
import json
from pathlib import Path

import pytest

from hopper_training.envs.end_to_end import END_TO_END
from robot_rl import AGENTS, RunDirectory
from robot_rl.runs.next_steps import WS_RUN_VARIABLE, RunContext, complete_lines, end_block, start_line
from robot_rl.training_node import _completed_summary

BC_DAGGER = AGENTS["bc_dagger"]


@pytest.fixture(autouse=True)
def not_under_ws_run(monkeypatch):
    """The commands as plain roslaunch's: no $WS_RUN (./ws run's, which its nodes read) from the caller."""
    monkeypatch.delenv(WS_RUN_VARIABLE, raising=False)


def context(agent, own_episodes=False, given=()):
    return RunContext(package="hopper_training", task="end_to_end", several_tasks=True, agent=agent,
                      default_agent="qlearn", run_path=Path("/runs/end_to_end-x/s0"), own_episodes=own_episodes,
                      given=given)


def summary(episodes):
    return {"episodes": episodes, "nepisodes": episodes, "completed": True, "env_steps": 1000,
            "headline_metric": "time_upright_s", "metrics_last_100": {"mean_time_upright_s": 9.5}}


def test_bc_dagger_counts_its_own_episodes_the_other_agents_the_tasks():
    params = BC_DAGGER.load_params()
    assert (params.bc_episodes, params.dagger_rounds, params.dagger_episodes) == (25, 5, 12)
    assert BC_DAGGER.own_episodes(params) == params.episodes() == 85
    assert END_TO_END.default_params().nepisodes == 200, "the task's count, which bc_dagger does not train"
    for name in ("qlearn", "dqn", "ppo", "sac", "rllib_ppo"):
        assert AGENTS[name].own_episodes(None) is None, name


def test_the_start_line_says_bc_dagger_s_own_episodes_not_the_task_s():
    line = start_line(context("bc_dagger", own_episodes=True), END_TO_END.env_id,
                      BC_DAGGER.own_episodes(BC_DAGGER.load_params()), 0, None, False)
    assert line == ("Results go to /runs/end_to_end-x/s0: MonopedEndToEnd-v0 with bc_dagger, 85 episodes (as agent "
                    "bc_dagger's params count them; nepisodes is not used)")
    assert start_line(context("dqn"), END_TO_END.env_id, 200, 0, None, False) == \
        "Results go to /runs/end_to_end-x/s0: MonopedEndToEnd-v0 with dqn, 200 episodes"


def test_bc_dagger_s_train_further_hint_is_a_new_run_not_more_nepisodes():
    own = context("bc_dagger", own_episodes=True)
    further = end_block(own, summary(85), None)[-1]
    assert further == ("  train further: roslaunch hopper_training main.launch task:=end_to_end agent:=bc_dagger "
                       "agent_config:=FILE (a new run: agent bc_dagger trains the episodes its params count, not "
                       "nepisodes:=, and a resume keeps the run's params)")
    complete = complete_lines(own, summary(85))[0]
    assert "nepisodes:=" not in complete.replace("not nepisodes:=", "") and "resume:=true" not in complete
    assert complete.startswith("Run /runs/end_to_end-x/s0 is complete (85 of 85 episodes): nothing to resume. To "
                               "train it further, train a new run with more: ")
    assert end_block(context("dqn"), summary(85), None)[-1] == \
        "  train further: roslaunch hopper_training main.launch task:=end_to_end agent:=dqn resume:=true run:=s0 " \
        "nepisodes:=170"


def test_a_step_budget_run_s_hint_doubles_its_env_steps_and_keeps_its_episode_budget():
    """A run that ended at max_steps:= (nepisodes:= set far above) trains further by more env steps: a hint of twice
    its episodes with the config's nepisodes would end the resumed run at once, or never reach the step budget."""
    budgeted = {**summary(1975), "nepisodes": 1000000, "max_steps": 200000}
    assert end_block(context("ppo"), budgeted, None)[-1] == \
        "  train further: roslaunch hopper_training main.launch task:=end_to_end agent:=ppo resume:=true run:=s0 " \
        "nepisodes:=1000000 max_steps:=400000"


def test_a_run_is_complete_by_its_own_budget(tmp_path):
    run = RunDirectory.create(tmp_path, BC_DAGGER.results_name(END_TO_END), END_TO_END.default_params().to_mapping(),
                              END_TO_END.metric_names, run_name="s0", checkpoint_name=BC_DAGGER.checkpoint_name)
    run.summary_json.write_text(json.dumps(summary(85)))
    assert _completed_summary(run, 85, 0) is not None, "bc_dagger's 85 episodes are its whole budget"
    assert _completed_summary(run, 200, 0) is None, "the task's 200 would be more to train"


def test_the_hint_repeats_the_launch_arguments_the_run_was_given():
    """A run started with its own config, agent params, backend or results folder is trained further with them: the
    resume would otherwise look for the run under the default results folder, or go on with the default config."""
    given = ("config:=/cfg/end_to_end_assist.yaml", "agent_config:=/cfg/ppo.yaml", "backend:=direct",
             "results_dir:=runs")
    budgeted = {**summary(1849), "nepisodes": 1000000, "max_steps": 3000000}
    assert end_block(context("ppo", given=given), budgeted, None)[-1] == \
        "  train further: roslaunch hopper_training main.launch task:=end_to_end agent:=ppo " \
        "config:=/cfg/end_to_end_assist.yaml agent_config:=/cfg/ppo.yaml backend:=direct results_dir:=runs " \
        "resume:=true run:=s0 nepisodes:=1000000 max_steps:=6000000"
    own = end_block(context("bc_dagger", own_episodes=True, given=given), summary(85), None)[-1]
    assert own.startswith("  train further: roslaunch hopper_training main.launch task:=end_to_end agent:=bc_dagger "
                          "config:=/cfg/end_to_end_assist.yaml backend:=direct results_dir:=runs agent_config:=FILE "
                          "(a new run"), "a new run's agent params replace the given ones"
