"""./ws's Python CLI (workspace_tools.cli) without running anything: its command table and usage, what each
command needs installed and runs, and the one-line errors of an unknown command or a wrong argument."""
import os

import pytest

import workspace_tools.cli as cli
from workspace_tools.paths import REPO
from workspace_tools.ws_messages import WsError

DOCUMENTED = {"run", "help", "python", "exec", "test", "lint", "bench", "rviz", "plot", "setup", "cluster", "sweep",
              "demo"}


@pytest.fixture(autouse=True)
def no_exec(monkeypatch):
    """Nothing is exec'd; a command's argv is recorded instead."""
    ran: list[list[str]] = []
    monkeypatch.setattr(os, "execvp", lambda file, argv: ran.append(list(argv)))
    monkeypatch.setattr(cli, "_agent_needs", lambda args: ["requirements requirements-deep.txt"]
                        if cli._last(args, "agent") in ("dqn", "ppo", "sac") else [])
    return ran


def test_every_documented_command_is_in_the_table_and_the_usage():
    assert DOCUMENTED | {"-h", "--help"} == set(cli.COMMANDS)
    for command in DOCUMENTED:
        assert f"./ws {command}" in cli.USAGE


def test_an_unknown_command_prints_the_usage_and_exits_1(capsys):
    assert cli.main(["fly"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(cli.USAGE) and err.endswith("[ws] error: unknown command 'fly'\n")
    assert cli.main(["needs", "fly"]) == 1


def test_no_command_prints_the_usage_and_exits_2(capsys):
    with pytest.raises(SystemExit) as exit_:
        cli.main([])
    assert exit_.value.code == 2 and capsys.readouterr().err == cli.USAGE


@pytest.mark.parametrize("argv, message", [
    (["run", "cube", "nepisodes"], "'nepisodes' is not a launch argument NAME:=VALUE (see ./ws help)"),
    (["run", "fly"], "unknown robot 'fly' (known: cube, hopper; see ./ws help)"),
    (["rviz", "fly"], "unknown robot 'fly' (known: cube, hopper)"),
    (["demo", "fly"], "unknown robot 'fly' (known: cube, hopper)"),
    (["demo", "cube", "policy:=../x"], "no shipped policy '../x' for cube (known: demo)"),
    (["demo", "cube", "a.mp4", "b.mp4"], "usage: ./ws demo [cube|hopper] [policy:=NAME] [VIDEO.mp4]"),
    (["cluster"], "usage: ./ws cluster start|join ADDRESS|stop|status"),
    (["cluster", "status", "now"], "usage: ./ws cluster status"),
    (["cluster", "join"], "usage: ./ws cluster join ADDRESS (HOST:PORT of the head)"),
    (["setup", "gpu"], "usage: ./ws setup [deep|distributed]"),
    (["exec"], "usage: ./ws exec CMD [ARGS...]"),
])
def test_a_wrong_argument_is_one_line_and_exit_1(argv, message, capsys):
    assert cli.main(["needs", *argv]) == 1
    assert capsys.readouterr().err == f"[ws] error: {message}\n"
    with pytest.raises(WsError, match=message.replace("(", r"\(").replace(")", r"\)").replace("[", r"\[")
                       .replace("|", r"\|").replace(".", r"\.")):
        cli.plan(argv)


def test_rviz_needs_a_display(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    with pytest.raises(WsError, match=r"^rviz:=true needs a display \(DISPLAY is not set\)$"):
        cli.plan(["run", "rviz:=True"])
    monkeypatch.setenv("DISPLAY", ":1")
    assert cli.plan(["run", "hopper", "rviz:=1"]).needs == ["apt rviz", "private-master"]


def test_rviz_shows_the_cube_sim_and_the_monoped_hopping_under_its_controller(monkeypatch):
    monkeypatch.setenv("DISPLAY", ":1")
    assert cli.plan(["rviz"]).argv == ["roslaunch", "pybullet_sim", "cube_sim.launch", "rviz:=true", "paused:=false"]
    assert cli.plan(["rviz", "hopper", "seed:=2"]).argv == [  # alone, the monoped falls within a minute
        "roslaunch", "hopper_training", "hop_controller.launch", "rviz:=true", "paused:=false", "seed:=2"]


@pytest.mark.parametrize("argv, needs", [
    (["run"], ["private-master"]),
    (["run", "agent:=qlearn", "agent:=sac", "cluster:=ray"],
     ["requirements requirements-deep.txt", "requirements requirements-distributed.txt", "private-master"]),
    (["test", "--quick", "test/unit/test_processes.py"], ["private-master"]),
    (["test", "--quick", "test/unit/test_agents.py::test_x", "-k", "x"],
     ["requirements requirements-deep.txt", "private-master"]),
    (["test", "--quick", "test/unit/test_cluster.py"], ["requirements requirements-distributed.txt", "private-master"]),
    (["test"], ["apt rviz", "apt python3-tk", "apt xvfb", "requirements requirements-deep.txt",
                "requirements requirements-distributed.txt", "requirements requirements-dev.txt", "private-master"]),
    (["bench", "--reps", "1"],
     ["requirements requirements-deep.txt", "requirements requirements-distributed.txt", "private-master"]),
    (["sweep", "hopper", "agent:=dqn"], ["requirements requirements-deep.txt",
                                         "requirements requirements-distributed.txt"]),
    (["sweep", "--help"], []),
    (["cluster", "start", "--num-cpus", "2"], ["requirements requirements-distributed.txt"]),
    (["demo", "hopper", "policy:=residual_forward_sac"], ["requirements requirements-deep.txt"]),
    (["plot"], ["apt python3-tk"]),
    (["lint"], ["requirements requirements-dev.txt"]),
    (["setup", "distributed"], ["requirements requirements-distributed.txt"]),
    (["python", "-c", "1"], []),
])
def test_what_a_command_needs_first(argv, needs, capsys):
    assert cli.main(["needs", *argv]) == 0
    assert capsys.readouterr().out.splitlines() == needs


def test_run_starts_the_robot_s_training_launch_with_its_results_folder(no_exec):
    assert cli.main(["run", "hopper", "task:=hop"]) == 127  # execvp replaced: it returns
    assert no_exec == [["rosrun", "workspace_tools", "roslaunch_checked.py", "hopper_training", "main.launch",
                        f"results_dir:={REPO}/training_results", "task:=hop"]]


def test_demo_plays_the_shipped_policy_into_a_video(no_exec, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    cli.main(["demo", "cube"])
    assert no_exec == [["rosrun", "moving_cube_training", "evaluate.py", "--run",
                        str(REPO / "moving_cube_training" / "policies" / "demo"), "--episodes", "1", "--video",
                        str(tmp_path / "demo_cube.mp4"), "--video-episodes", "1"]]


def test_sweep_results_go_where_run_puts_them_unless_given(no_exec):
    cli.main(["sweep", "cube", "seeds:=0-1"])
    cli.main(["sweep", "cube", "results_dir:=/tmp/x"])
    assert no_exec[0][-1] == f"results_dir:={REPO}/training_results"
    assert no_exec[1][-1] == "results_dir:=/tmp/x"
