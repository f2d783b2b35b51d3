"""The sweep's grammar (seeds, lists of any training or agent parameter, one-line errors), its trials and
their names, and the table writer (workspace_tools.sweep_spec, sweep_table; no Ray)."""
import csv
import io

import pytest
import yaml

from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from robot_rl import MAX_COUNT, find_agent
from workspace_tools import sweep_spec
from workspace_tools.sweep_spec import SweepError, parse_seeds, parse_sweep, trial_config, trial_name
from workspace_tools.sweep_table import TrialResult, plot_curves, table_csv, table_markdown


@pytest.mark.parametrize("text, seeds", [("0-9", tuple(range(10))), ("0,3,5", (0, 3, 5)), ("0-2,7", (0, 1, 2, 7)),
                                         ("4", (4,)), (" 1 - 2 ", (1, 2))])
def test_seeds_are_ranges_and_lists(text, seeds):
    assert parse_seeds(text) == seeds


@pytest.mark.parametrize("text, message", [
    ("5-2", "seeds:=5-2: the range 5-2 ends before it starts"),
    ("a", "seeds:=a: 'a' is not a seed or a range FIRST-LAST of seeds (e.g. seeds:=0-9 or seeds:=0,3,5)"),
    ("1,,2", "seeds:=1,,2: '' is not a seed"),
    ("-1", "seeds:=-1: '-1' is not a seed"),
    ("0-2,1", "seeds:=0-2,1: seed 1 is given twice"),
    ("0-2147483648", "seeds:=0-2147483648: seeds go from 0 to 2147483647"),
])
def test_bad_seeds_get_one_line(text, message):
    with pytest.raises(SweepError) as error:
        parse_seeds(text)
    assert str(error.value).startswith(message) and "\n" not in str(error.value)


def test_trials_are_every_seed_times_every_combination_named_by_what_varies():
    spec = parse_sweep(["cube", "seeds:=0-1", "alpha:=0.1,0.2", "gamma:=0.9", "nepisodes:=3"])
    trials = spec.trials()
    assert [t.name for t in trials] == ["seed=0,alpha=0.1", "seed=0,alpha=0.2", "seed=1,alpha=0.1",
                                        "seed=1,alpha=0.2"]
    assert trials[3].seed == 1 and trials[3].changes == {"alpha": 0.2, "gamma": 0.9, "nepisodes": 3}
    assert spec.varied == ("alpha",)
    assert spec.grid_args == ("cube", "seeds:=0-1", "alpha:=0.1,0.2", "gamma:=0.9", "nepisodes:=3")


def test_values_are_typed_as_the_yaml_types_them():
    spec = parse_sweep(["hopper", "task:=hop", "q_init:=0,5000", "exploration:=noise,epsilon_greedy"])
    assert spec.task.name == "hop" and spec.seeds == (ONE_DISK_WALK.default_params().seed,)
    assert dict(spec.grid) == {"q_init": (0.0, 5000.0), "exploration": ("noise", "epsilon_greedy")}
    assert spec.trials()[0].name == "seed=0,q_init=0.0,exploration=noise"


def test_trial_names_are_safe_folder_names():
    assert trial_name(3, {"alpha": 0.2, "first_visit": "a/b c"}) == "seed=3,alpha=0.2,first_visit=a_b_c"
    assert trial_name(0, {"epsilon_min": 1e-05, "flag": True}) == "seed=0,epsilon_min=1e-05,flag=true"


@pytest.mark.parametrize("argv, message", [
    (["cube", "foo:=1"], "unknown parameter 'foo': not a training parameter of task one_disk_walk (known: alpha,"),
    (["cube", "alpha:=2"], "alpha:=2: parameter 'alpha' = 2.0 out of range [0.0, 1.0]"),
    (["cube", "alpha:=0.1,x"], "alpha:=0.1,x: parameter 'alpha' expected float, got 'x' (str)"),
    (["cube", "alpha:=0.1,,0.2"], "alpha:=0.1,,0.2: an empty value"),
    (["cube", "alpha:=0.1,0.1"], "alpha:=0.1,0.1: the value 0.1 is given twice"),
    (["cube", "exploration:=greedy"], "exploration:=greedy: parameter 'exploration' = 'greedy' is not one of"),
    (["cube", "seed:=1"], "seed:= is not a sweep argument: give the seeds with seeds:="),
    (["cube", "alpha:=0.1", "alpha:=0.2"], "alpha:= is given twice"),
    (["cube", "alpha"], "'alpha' is not an argument NAME:=VALUE"),
    (["robot"], "unknown robot 'robot' (known: cube, hopper)"),
    (["cube", "task:=hop"], "unknown task 'hop' (known: one_disk_walk)"),
    (["cube", "agent:=a2c"], "unknown agent 'a2c' (known: qlearn, dqn, ppo, sac, bc_dagger, ppo_finetune, rllib_ppo)"),
    (["cube", "name:=../x"], "name:=../x: a sweep's name is letters, digits and ._-"),
    (["cube", "resume:=maybe"], "resume:=maybe: expected true or false"),
    (["cube", "concurrent:=0"], "concurrent:=0: expected a whole number >= 1"),
    (["cube", "init_cube_pose:=1"], "unknown parameter 'init_cube_pose'"),
])
def test_bad_arguments_get_one_line(argv, message):
    with pytest.raises(SweepError) as error:
        parse_sweep(argv)
    assert str(error.value).startswith(message) and "\n" not in str(error.value)


def test_an_agent_parameter_goes_to_the_agent_config_and_names_the_trials():
    spec = parse_sweep(["cube", "agent:=dqn", "seeds:=0", "learning_rate:=1e-4,3e-4", "alpha:=0.2", "max_steps:=500"])
    assert spec.agent_grid == ("learning_rate",) and spec.max_steps == 500
    assert dict(spec.grid) == {"learning_rate": (1e-4, 3e-4), "alpha": (0.2,)}
    trials = spec.trials()
    assert [t.name for t in trials] == ["seed=0,learning_rate=0.0001", "seed=0,learning_rate=0.0003"]
    assert trials[1].changes == {"alpha": 0.2} and trials[1].agent_changes == {"learning_rate": 3e-4}
    agent = find_agent("dqn")
    document = sweep_spec.trial_agent_config(agent, ONE_DISK_WALK, trials[1])
    assert agent.load_params_from(document, "trial") == \
        agent.load_params(agent.config_for(ONE_DISK_WALK)).with_changes("expected", learning_rate=3e-4)
    config = ONE_DISK_WALK.params_from_document(trial_config(ONE_DISK_WALK, trials[1], spec.max_steps), "trial")
    assert config.nepisodes == MAX_COUNT and config.alpha == 0.2, "the step budget decides, not the episodes"
    assert sweep_spec.trial_agent_config(find_agent("qlearn"), ONE_DISK_WALK, trials[1]) is None


@pytest.mark.parametrize("argv, message", [
    (["cube", "agent:=dqn", "learning_rate:=2"], "learning_rate:=2: parameter 'learning_rate' = 2.0 out of range"),
    (["cube", "agent:=ppo", "exploration_fraction:=0.1"], "unknown parameter 'exploration_fraction': not a "
     "training parameter of task one_disk_walk (known: alpha,"),
    (["cube", "learning_rate:=0.1"], "unknown parameter 'learning_rate'"),
    (["cube", "max_steps:=100"], "max_steps:= is a deep agent's budget of env steps; agent qlearn trains"),
    (["cube", "agent:=dqn", "max_steps:=0"], "max_steps:=0: expected a whole number >= 1"),
])
def test_bad_agent_arguments_get_one_line(argv, message):
    with pytest.raises(SweepError) as error:
        parse_sweep(argv)
    assert str(error.value).startswith(message) and "\n" not in str(error.value)


def test_a_name_that_is_both_a_task_s_and_the_agent_s_parameter_is_refused(monkeypatch):
    monkeypatch.setattr(sweep_spec, "agent_sweepable_params", lambda agent, task: ("learning_rate", "alpha"))
    with pytest.raises(SweepError, match=r"^alpha:= is ambiguous: both a training parameter of task one_disk_walk "
                                         r"and one of agent dqn's"):
        parse_sweep(["cube", "agent:=dqn", "alpha:=0.1,0.2"])


def test_a_trial_config_is_the_task_yaml_with_the_trial_in_it():
    trial = parse_sweep(["cube", "seeds:=7", "alpha:=0.3", "nepisodes:=3"]).trials()[0]
    document = trial_config(ONE_DISK_WALK, trial)
    params = ONE_DISK_WALK.params_from_document(yaml.safe_load(yaml.safe_dump(document)), "trial")
    assert params == ONE_DISK_WALK.default_params().with_changes("expected", seed=7, alpha=0.3, nepisodes=3)


def result(name, seed, alpha, greedy, curve=(0.0, 1.0)):
    return TrialResult(name=name, seed=seed, params={"alpha": alpha}, episodes=200, env_steps=12345,
                       wall_time_s=21.4, train={"mean_y_distance": 1.0, "success_rate": 0.5},
                       greedy={"mean_return": 1.5e5, "success_rate": greedy}, random={"success_rate": 0.0},
                       curve=list(curve))


RESULTS = [result("seed=0,alpha=0.1", 0, "0.1", 1.0), result("seed=1,alpha=0.1", 1, "0.1", 0.8),
           result("seed=0,alpha=0.2", 0, "0.2", None)]


def test_the_table_has_a_row_per_trial_and_a_summary_per_combination():
    text = table_markdown(RESULTS, "Sweep x", "success_rate")
    lines = text.splitlines()
    assert lines[0] == "Sweep x"
    assert lines[2] == ("| trial | seed | alpha | episodes | env steps | wall time (s) | training mean_y_distance | "
                        "training success_rate | greedy mean_return | greedy success_rate | random success_rate |")
    assert lines[4] == "| seed=0,alpha=0.1 | 0 | 0.1 | 200 | 12345 | 21 | 1 | 0.5 | 150000 | 1 | 0 |"
    assert lines[6] == "| seed=0,alpha=0.2 | 0 | 0.2 | 200 | 12345 | 21 | 1 | 0.5 | 150000 | n/a | 0 |"
    assert "| 0.1 | 0,1 | 0.9 (0.8-1) | 0.5 (0.5-0.5) |" in lines
    assert "| 0.2 | 0 | n/a | 0.5 (0.5-0.5) |" in lines


def test_the_csv_has_every_number_in_full():
    rows = list(csv.reader(io.StringIO(table_csv(RESULTS))))
    assert rows[0] == ["trial", "seed", "alpha", "episodes", "env_steps", "wall_time_s", "train_mean_y_distance",
                       "train_success_rate", "greedy_mean_return", "greedy_success_rate", "random_success_rate"]
    assert rows[1] == ["seed=0,alpha=0.1", "0", "0.1", "200", "12345", "21.4", "1.0", "0.5", "150000.0", "1.0", "0.0"]
    assert rows[3][9] == "" and len(rows) == 4


def test_the_plot_is_a_png(tmp_path):
    plot_curves(RESULTS, "success", "sweep x", tmp_path / "curves.png")
    assert (tmp_path / "curves.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
