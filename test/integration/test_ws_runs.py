"""What a newcomer sees of `./ws run` (issue 41): a second terminal's `./ws exec` meets the run's master,
a run ends with its block and the next commands, a resume of a complete run says so, and the cube's default
run prints at most 40 lines. Through ./ws itself, with the runs recorded in a folder of the test's own."""
import json
import os
import re
import signal
import subprocess
from pathlib import Path

import yaml

from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from workspace_tools.paths import REPO
from workspace_tools.processes import stop, wait_for


def ws_env(tmp_path: Path) -> dict[str, str]:
    """The environment of a user's terminal: no ROS_MASTER_URI (./ws run picks the port), the runs recorded
    under tmp_path."""
    env = {key: value for key, value in os.environ.items() if not key.startswith("ROS_")}
    return {**env, "WS_RUNS_DIR": str(tmp_path / "runs")}


def cube_config(tmp_path: Path, **changes) -> Path:
    document = yaml.safe_load(ONE_DISK_WALK.config_path.read_text())
    document["moving_cube"].update(changes)
    path = tmp_path / "config.yaml"
    path.write_text(yaml.safe_dump(document))
    return path


def ws(tmp_path, *args, timeout=300):
    """./ws ARGS in tmp_path: (the result, its stdout and stderr as a terminal shows them, interleaved)."""
    result = subprocess.run([str(REPO / "ws"), *args], env=ws_env(tmp_path), cwd=tmp_path, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, timeout=timeout)
    return result, result.stdout


def test_ws_exec_in_another_terminal_meets_the_run_s_master(tmp_path):
    run = subprocess.Popen([str(REPO / "ws"), "run", "nepisodes:=100000", "video:=false",
                            f"results_dir:={tmp_path / 'results'}"], env=ws_env(tmp_path), cwd=tmp_path,
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        record = wait_for(lambda: next((tmp_path / "runs").glob("*.json"), None), 120,
                          "./ws run's record in WS_RUNS_DIR (roslaunch_checked.py writes it once the master is up)")
        recorded = json.loads(record.read_text())
        result = subprocess.run([str(REPO / "ws"), "exec", "rosparam", "get", "/run_id"], env=ws_env(tmp_path),
                                cwd=tmp_path, capture_output=True, text=True, timeout=60)
        output = result.stdout + result.stderr
        assert result.returncode == 0, output
        assert result.stdout.strip() == recorded["run_id"], output
        assert "[ws] joining the run of `./ws run cube nepisodes:=100000" in result.stderr, output
        assert recorded["master_uri"] in result.stderr and result.stderr.count("\n") == 1, output
    finally:
        run.send_signal(signal.SIGINT)  # the launcher (./ws exec'd into it): its pid is the Popen's
        try:
            output = run.communicate(timeout=60)[0]
        finally:
            stop(run)
    assert run.returncode == 130, output[-3000:]
    assert output.startswith("[ws] this run's ROS master: http://127.0.0.1:") or \
        output.startswith("[ws] port 11311 is taken"), output[:500]
    assert not list((tmp_path / "runs").glob("*.json")), "the record is removed when the run ends"
    # A record whose launcher is gone is stale: ignored (and removed), ./ws exec uses the default master.
    (tmp_path / "runs" / "999999.json").write_text(json.dumps({**recorded, "pid": 2**22 + 12345}))
    result, output = ws(tmp_path, "exec", "true", timeout=60)
    assert result.returncode == 0 and "joining" not in output, output
    assert not (tmp_path / "runs" / "999999.json").exists()


def test_two_runs_started_together_take_two_masters(tmp_path):
    """Two `./ws run` started at once, no ROS_MASTER_URI: the first to claim 11311 takes it (if it is free), the
    other a free port; before the claim both could see 11311 free and meet on one master."""
    command = [str(REPO / "ws"), "run", "nepisodes:=100000", "video:=false", f"results_dir:={tmp_path / 'results'}"]
    runs = [subprocess.Popen(command, env=ws_env(tmp_path), cwd=tmp_path, stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, text=True, start_new_session=True) for _ in range(2)]
    outputs = []
    try:
        records = wait_for(lambda: (lambda found: found if len(found) == 2 else None)(
            sorted((tmp_path / "runs").glob("*.json"))), 180,
            "two records of ./ws run in WS_RUNS_DIR (roslaunch_checked.py writes one once its master is up)")
        masters = {json.loads(record.read_text())["master_uri"] for record in records}
        assert len(masters) == 2, masters
    finally:
        for run in runs:
            run.send_signal(signal.SIGINT)
        for run in runs:
            try:
                outputs.append(run.communicate(timeout=60)[0])
            finally:
                stop(run)
    assert [run.returncode for run in runs] == [130, 130], [output[-2000:] for output in outputs]
    assert not (tmp_path / "runs" / "port-11311.claim").exists(), "the run that claimed 11311 let it go"


def test_a_run_ends_with_its_block_and_a_resume_of_it_says_it_is_complete(tmp_path):
    config = cube_config(tmp_path, nepisodes=3, nsteps=10)
    result, output = ws(tmp_path, "run", "run:=first", f"config:={config}", "results_dir:=results")
    assert result.returncode == 0, output[-3000:]
    lines = output.splitlines()
    assert not [line for line in lines if re.search(r"EP: \d|PARAMETERS|PICTURE", line)], output
    done = next(i for i, line in enumerate(lines) if "Done: results/moving_cube/first/ (3 episodes" in line)
    block = [re.sub(r"^\[INFO\] \[[^]]*\]: ", "", line) for line in lines[done:]]
    assert len(block) == 5, output[-3000:]
    assert re.match(r"  success_rate \S+ over the last 3 training episodes", block[1]), block
    assert block[2] == "  evaluate it:   ./ws exec rosrun moving_cube_training evaluate.py --run " \
                       "results/moving_cube/first"
    assert block[3].startswith("  play it:       ./ws demo cube run:=results/moving_cube/first (or open "), block
    # the run's own config and results folder: a resume without them would not find the run
    assert block[4] == f"  train further: ./ws run cube config:={config} results_dir:={tmp_path}/results " \
                       "resume:=true run:=first nepisodes:=6"

    resumed, output = ws(tmp_path, "run", "run:=first", f"config:={config}", "results_dir:=results", "resume:=true")
    assert resumed.returncode == 0, output[-3000:]
    assert "Run results/moving_cube/first is complete (3 of 3 episodes): nothing to resume. To train it further, " \
           f"give more episodes: ./ws run cube config:={config} results_dir:={tmp_path}/results resume:=true " \
           "run:=first nepisodes:=6" in output, output[-3000:]
    assert "Training complete" not in output and "Resuming" not in output, output[-3000:]


def test_the_cube_s_default_run_prints_at_most_40_lines(tmp_path):
    """The README's first command (200 episodes, about a minute): ends with the command to train further."""
    result, output = ws(tmp_path, "run", "results_dir:=results", timeout=900)
    assert result.returncode == 0, output[-3000:]
    lines = output.splitlines()
    assert len(lines) <= 40, output
    assert f"train further: ./ws run cube results_dir:={tmp_path}/results resume:=true run:=" in lines[-1], output


def test_three_ws_at_once_after_a_script_changed_all_run(tmp_path):
    """Three ./ws at once after a script catkin installs changed: one rebuilds while the others wait on the setup
    lock (without it two makes in the one build folder broke each other's configure: "catkin build failed")."""
    os.utime(REPO / "hopper_training" / "scripts" / "evaluate.py")  # newer than the build: catkin configures again
    commands = [subprocess.Popen([str(REPO / "ws"), "exec", "true"], env=ws_env(tmp_path), cwd=tmp_path,
                                 stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True) for _ in range(3)]
    try:
        outputs = [command.communicate(timeout=600)[0] for command in commands]
    finally:
        for command in commands:
            stop(command)
    for command, output in zip(commands, outputs):
        assert command.returncode == 0 and "catkin build failed" not in output, output
