"""./ws's Python CLI (workspace_tools.cli) without running anything: its command table and usage, what each
command needs installed and runs, and the one-line errors of an unknown command or a wrong argument."""
import os

import pytest

import workspace_tools.cli as cli
import workspace_tools.live_runs as cli_live_runs
from workspace_tools.paths import REPO
from workspace_tools.ws_messages import WsError

DOCUMENTED = {"run", "help", "python", "exec", "test", "lint", "bench", "rviz", "plot", "setup", "cluster", "sweep",
              "demo"}


@pytest.fixture(autouse=True)
def no_exec(monkeypatch, tmp_path):
    """Nothing is exec'd; a command's argv is recorded instead. The variables ./ws run sets for the process it would
    exec are put back after each test (setenv records them as unset, so the run's values do not leak into the
    tests after these: robot_rl.runs.next_steps reads WS_RUN). Runs and port claims go to a folder of the test's."""
    for variable in (cli.WS_RUN_VARIABLE, "WS_RUN_RECORD", "ROS_MASTER_URI"):
        monkeypatch.setenv(variable, os.environ.get(variable, ""))
    monkeypatch.setenv("WS_RUNS_DIR", str(tmp_path / "runs"))
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
    (["demo", "cube", "a.mp4", "b.mp4"],
     "usage: ./ws demo [cube|hopper] [policy:=NAME|run:=RUN_FOLDER] [push:=V] [seed:=N] [VIDEO.mp4]"),
    (["demo", "hopper", "speed:=1"],
     "usage: ./ws demo [cube|hopper] [policy:=NAME|run:=RUN_FOLDER] [push:=V] [seed:=N] [VIDEO.mp4]"),
    (["demo", "hopper", "push:=1", "push:=2"], cli.DEMO_USAGE),
    (["demo", "hopper", "policy:=demo", "run:=/tmp"], cli.DEMO_USAGE),
    (["demo", "hopper", "push:="], "push:=: the kicks' speed in m/s, a number of 0 or more (e.g. push:=0.75)"),
    (["demo", "hopper", "seed:=-1"], "seed:=-1: the episode's seed, a whole number of 0 or more (e.g. seed:=1000)"),
    (["demo", "hopper", "push:=-1"], "push:=-1: the kicks' speed in m/s, a number of 0 or more (e.g. push:=0.75)"),
    (["demo", "hopper", "push:=nan"], "push:=nan: the kicks' speed in m/s, a number of 0 or more (e.g. push:=0.75)"),
    (["demo", "cube", "run:=/nonexistent"],
     "run:=/nonexistent: no such run folder (a training_results/<task>/<run>/ folder)"),
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
    assert cli.plan(["run", "hopper", "rviz:=1"]).needs == ["apt rviz"]


def test_rviz_shows_the_cube_sim_and_the_monoped_hopping_under_its_controller(monkeypatch):
    monkeypatch.setenv("DISPLAY", ":1")
    assert cli.plan(["rviz"]).argv == ["roslaunch", "pybullet_sim", "cube_sim.launch", "rviz:=true", "paused:=false"]
    assert cli.plan(["rviz", "hopper", "seed:=2"]).argv == [  # alone, the monoped falls within a minute
        "roslaunch", "hopper_training", "hop_controller.launch", "rviz:=true", "paused:=false", "seed:=2"]


@pytest.mark.parametrize("argv, needs", [
    (["run"], []),  # its master: 11311, or a free port if taken (chosen when it runs)
    (["run", "agent:=qlearn", "agent:=sac", "cluster:=ray"],
     ["requirements requirements-deep.txt", "requirements requirements-distributed.txt"]),
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
    (["demo", "hopper", "policy:=end_to_end"], []),  # the bc_dagger student plays in numpy
    (["plot"], ["apt python3-tk"]),
    (["lint"], ["requirements requirements-dev.txt"]),
    (["setup", "distributed"], ["requirements requirements-distributed.txt"]),
    (["python", "-c", "1"], []),
])
def test_what_a_command_needs_first(argv, needs, capsys):
    assert cli.main(["needs", *argv]) == 0
    assert capsys.readouterr().out.splitlines() == needs


def test_run_starts_the_robot_s_training_launch_quiet_with_its_results_folder(no_exec, monkeypatch):
    monkeypatch.setenv("WS_CALLER_MASTER", "http://127.0.0.1:1")
    monkeypatch.setenv("ROS_MASTER_URI", "http://127.0.0.1:1")
    assert cli.main(["run", "hopper", "task:=hop"]) == 127  # execvp replaced: it returns
    assert cli.main(["run", "cube", "quiet:=false"]) == 127
    assert no_exec == [["rosrun", "workspace_tools", "roslaunch_checked.py", "--quiet", "hopper_training",
                        "main.launch", f"results_dir:={REPO}/training_results", "quiet:=true", "task:=hop"],
                       ["rosrun", "workspace_tools", "roslaunch_checked.py", "moving_cube_training", "main.launch",
                        f"results_dir:={REPO}/training_results", "quiet:=false"]]
    assert os.environ["ROS_MASTER_URI"] == "http://127.0.0.1:1", "the caller's master wins"


def test_run_takes_port_11311_when_free_else_another_and_says_so(no_exec, monkeypatch, capsys):
    monkeypatch.setenv("WS_CALLER_MASTER", "")
    monkeypatch.setenv("ROS_MASTER_URI", "http://127.0.0.1:11311")
    for free in (True, False):
        monkeypatch.setattr(cli_live_runs, "port_is_free", lambda port, host="127.0.0.1", free=free: free)
        cli.main(["run"])
        line = capsys.readouterr().err
        if free:
            assert os.environ["ROS_MASTER_URI"] == "http://127.0.0.1:11311" and line.count("\n") == 1, line
        else:
            assert os.environ["ROS_MASTER_URI"] != "http://127.0.0.1:11311", line
            assert line.startswith("[ws] port 11311 is taken") and os.environ["ROS_MASTER_URI"] in line, line


def test_demo_plays_the_shipped_policy_into_demos_and_never_overwrites(no_exec, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(cli, "DEMOS", tmp_path / "demos")
    cli.main(["demo", "cube"])
    (tmp_path / "demos" / "demo_cube.mp4").write_bytes(b"a video")
    cli.main(["demo", "cube"])
    shipped = str(REPO / "moving_cube_training" / "policies" / "demo")
    assert no_exec == [["rosrun", "moving_cube_training", "evaluate.py", "--run", shipped, "--episodes", "1", "--video",
                        str(tmp_path / "demos" / name), "--video-episodes", "1"]
                       for name in ("demo_cube.mp4", "demo_cube-2.mp4")]
    assert capsys.readouterr().err == "[ws] demos/demo_cube.mp4 exists: this video goes to demos/demo_cube-2.mp4\n"
    monkeypatch.chdir(tmp_path / "demos")
    assert cli.main(["demo", "cube", "demo_cube.mp4"]) == 1
    assert capsys.readouterr().err == "[ws] error: demo_cube.mp4 exists: give another name (or delete it)\n"


def test_demo_with_pushes_and_a_seed_passes_them_to_evaluate_in_any_order(no_exec, tmp_path):
    video = str(tmp_path / "kicked.mp4")
    cli.main(["demo", "hopper", "policy:=hop_in_place_push075", "push:=0.75", video])
    cli.main(["demo", "hopper", "seed:=1000", video, "push:=0.75", "policy:=hop_in_place_push075"])
    shipped = str(REPO / "hopper_training" / "policies" / "hop_in_place_push075")
    played = ["rosrun", "hopper_training", "evaluate.py", "--run", shipped, "--episodes", "1", "--video", video,
              "--video-episodes", "1", "--push", "0.75"]
    assert no_exec == [played, [*played, "--seed", "1000"]]


def test_sweep_results_go_where_run_puts_them_unless_given(no_exec):
    cli.main(["sweep", "cube", "seeds:=0-1"])
    cli.main(["sweep", "cube", "results_dir:=/tmp/x"])
    assert no_exec[0][-1] == f"results_dir:={REPO}/training_results"
    assert no_exec[1][-1] == "results_dir:=/tmp/x"
