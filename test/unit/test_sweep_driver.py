"""The sweep driver's folder, before any Ray (workspace_tools.sweep, sweep_folder): one driver per sweep (its
lock), a trial's run folder removed only under the run's lock, a resume that finds its sweep by name whatever its
task and agent, and a start that fails leaving no half-made folder."""
import subprocess
import sys
import textwrap

import pytest
import yaml

from robot_rl import RunDirectory
from workspace_tools import sweep, sweep_folder
from workspace_tools.paths import REPO
from workspace_tools.sweep import TrialJob, _train
from workspace_tools.sweep_folder import open_sweep
from workspace_tools.sweep_spec import SweepError, parse_sweep

HOLD = textwrap.dedent("""
    import sys
    from pathlib import Path
    {body}
    print("held", flush=True)
    sys.stdin.read()
""")


class Holder:
    """A process that runs `body` (which takes a lock) and holds what it took until closed."""

    def __init__(self, body: str):
        self.process = subprocess.Popen([sys.executable, "-c", HOLD.format(body=body)], cwd=REPO, text=True,
                                        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        assert self.process.stdout is not None and self.process.stdin is not None
        line = self.process.stdout.readline()  # bounded by the child: it prints or ends
        assert line == "held\n", self.process.communicate(timeout=30)[1]

    def close(self) -> None:
        assert self.process.stdin is not None
        self.process.stdin.close()
        self.process.wait(30)


def new_sweep(results, *args):
    return open_sweep(parse_sweep(["cube", "seeds:=0", "nepisodes:=2", "name:=race", f"results_dir:={results}",
                                    *args]))


def test_a_second_driver_of_a_running_sweep_is_refused_in_one_line(tmp_path, capsys):
    results = tmp_path / "results"
    holder = Holder("from workspace_tools.sweep_folder import open_sweep\n"
                    "from workspace_tools.sweep_spec import parse_sweep\n"
                    f"open_sweep(parse_sweep(['cube', 'seeds:=0', 'nepisodes:=2', 'name:=race', "
                    f"'results_dir:={results}']))")
    try:
        code = sweep.main(["cube", "name:=race", "resume:=true", f"results_dir:={results}"])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 1 and len(err) == 1, err
        assert "another ./ws sweep is running it" in err[0] and ".lock" in err[0], err
        with pytest.raises(SweepError, match="exists already"):
            new_sweep(results)
    finally:
        holder.close()
    spec, sweep_dir = open_sweep(parse_sweep(["cube", "name:=race", "resume:=true", f"results_dir:={results}"]))
    assert sweep_dir == results / "moving_cube" / "race" and spec.seeds == (0,)
    other = subprocess.run([sys.executable, "-c", "from pathlib import Path\nfrom workspace_tools.sweep_folder import "
                            f"lock_sweep\nlock_sweep(Path({str(sweep_dir)!r}))"], cwd=REPO, capture_output=True,
                           text=True, timeout=60)
    assert other.returncode != 0 and "SweepLockedError" in other.stderr, "the resume holds the sweep's lock"


def test_a_trial_run_that_a_training_holds_is_never_removed(tmp_path, monkeypatch):
    """A run folder without a checkpoint is started anew, but not while a training process holds its lock."""
    run = RunDirectory(tmp_path / "moving_cube" / "seed=0")  # made here without taking its lock
    run.path.mkdir(parents=True)
    run.episodes_csv.write_text("episode,steps,return,epsilon,sim_time,wall_time\n1,10,1.0,0.9,0.1,0.1\n")
    job = TrialJob(name="seed=0", seed=0, params={}, sweep_dir=str(tmp_path / "moving_cube"),
                   package="moving_cube_training", task="one_disk_walk", agent="qlearn", results_name="moving_cube",
                   checkpoint_name="qtable.json", eval_episodes=1, eval_seed=0)

    def no_training(*args, **kwargs):
        raise AssertionError("no training may start over a run another process trains")
    holder = Holder(f"from robot_rl import RunDirectory\nRunDirectory(Path({str(run.path)!r})).lock()")
    monkeypatch.setattr(sweep.subprocess, "Popen", no_training)
    try:
        with pytest.raises(RuntimeError, match="another process is training its run"):
            _train(job)
    finally:
        holder.close()
    assert run.read_episodes()[0].episode == 1, "the run is as it was"


def write_sweep(results, results_name, name, args, task, agent):
    folder = results / results_name / name
    folder.mkdir(parents=True)
    (folder / "sweep.yaml").write_text(yaml.safe_dump({"args": args, "task": task, "agent": agent}))
    return folder


def test_a_resume_finds_its_sweep_by_name_whatever_its_task_and_agent(tmp_path):
    results = tmp_path / "results"
    folder = write_sweep(results, "hop_in_place-dqn", "race", ["hopper", "task:=hop_in_place", "agent:=ppo",
                                                               "seeds:=0-1"], "MonopedHopInPlace-v0", "ppo")
    for args in (["hopper"], ["hopper", "task:=hop_in_place"], ["hopper", "task:=hop_in_place", "agent:=ppo"]):
        assert sweep_folder.find_sweep(parse_sweep([*args, "name:=race", "resume:=true", f"results_dir:={results}"])) \
            == folder
    with pytest.raises(SweepError, match=r"no cube sweep 'race' .*there is: .*hop_in_place-dqn/race \(./ws sweep "
                                         r"hopper task:=hop_in_place"):
        sweep_folder.find_sweep(parse_sweep(["cube", "name:=race", "resume:=true", f"results_dir:={results}"]))
    write_sweep(results, "monoped", "race", ["hopper", "seeds:=0"], "Monoped-v0", "qlearn")
    with pytest.raises(SweepError, match="is in 2 results folders .*add the task:= and agent:="):
        sweep_folder.find_sweep(parse_sweep(["hopper", "name:=race", "resume:=true", f"results_dir:={results}"]))
    assert sweep_folder.find_sweep(parse_sweep(["hopper", "task:=hop_in_place", "name:=race", "resume:=true",
                                         f"results_dir:={results}"])) == folder


def test_a_new_sweep_of_a_name_taken_under_another_task_is_refused(tmp_path):
    results = tmp_path / "results"
    write_sweep(results, "monoped", "race", ["hopper", "seeds:=0"], "Monoped-v0", "qlearn")
    with pytest.raises(SweepError, match="monoped/race exists already"):
        new_sweep(results)
    assert not (results / "moving_cube").exists()


@pytest.mark.parametrize("args, message", [
    (["agent:=sac"], "agent sac on MovingCubeOneDiskWalk-v0: SAC needs Box (continuous) actions"),
    (["seeds:=0-2147483647"], "seeds:=0-2147483647: more than 1000 seeds"),
    (["seeds:=0-9", "alpha:=0.1,0.2,0.3,0.4,0.5,0.6,0.7,0.8,0.9", "gamma:=0.1,0.2,0.3,0.4,0.5,0.6,0.7,0.8,0.9,1.0,"
      "0.95,0.99"], "1080 trials (10 seeds x 9 alpha x 12 gamma): a sweep has at most 1000 trials"),
], ids=["agent_that_does_not_fit", "seeds_beyond_the_bound", "grid_beyond_the_bound"])
def test_a_sweep_that_cannot_run_is_refused_before_its_folder_is_made(tmp_path, capsys, args, message):
    results = tmp_path / "results"
    code = sweep.main(["cube", *args, "name:=bad", f"results_dir:={results}"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and message in err[0], err
    assert not results.exists(), "nothing made"


def test_a_start_that_fails_after_its_folder_is_made_leaves_none(tmp_path, monkeypatch):
    results = tmp_path / "results"

    def full_disk(path, text):
        raise OSError(28, "No space left on device", str(path))
    monkeypatch.setattr(sweep_folder, "write_text_atomic", full_disk)
    with pytest.raises(OSError, match="No space left"):
        new_sweep(results)
    assert list((results / "moving_cube").iterdir()) == [], "no half-made sweep blocks its name"
    monkeypatch.undo()
    spec, folder = new_sweep(results)
    assert (folder / "sweep.yaml").is_file() and spec.name == "race"
