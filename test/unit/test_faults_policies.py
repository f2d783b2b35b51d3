"""Faults of trained policies (issue 42): evaluate.py and ./ws demo play no deep policy whose model.zip is not the
one its agent.json recorded, and end with one line on a damaged one or a bad option; ship_policy.py ships nothing
it cannot load back and replaces a policy folder whole."""
import hashlib
import io
import json
import os
import shutil
import zipfile

import pytest

from hopper_training import TASKS as HOPPER_TASKS
from hopper_training import scripted_policies
from moving_cube_training import TASKS as CUBE_TASKS
from robot_rl import evaluation
from workspace_tools.paths import REPO
from workspace_tools.ship import ship_run

SHIPPED = REPO / "hopper_training" / "policies"
CUBE_DEMO = REPO / "moving_cube_training" / "policies" / "demo"


def evaluate(capsys, *args, tasks=HOPPER_TASKS, policies=None):
    """evaluate.py's main in this process: (exit code, stdout, stderr)."""
    try:
        code = evaluation.main([*args], tasks, "evaluate_test", policies)
    except SystemExit as exit_:
        code = exit_.code
    out, err = capsys.readouterr()
    return code, out, err


def one_line(err: str) -> str:
    lines = err.splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def copied(tmp_path, name="residual_in_place_sac"):
    shutil.copytree(SHIPPED / name, tmp_path / name)
    return tmp_path / name


def set_digest(policy, digest):
    checkpoint = json.loads((policy / "agent.json").read_text())
    if digest is None:
        del checkpoint["model_sha256"]
    else:
        checkpoint["model_sha256"] = digest
    (policy / "agent.json").write_text(json.dumps(checkpoint))


@pytest.mark.deep
@pytest.mark.parametrize("damage, expected", [
    ("another_policys_weights", "not the model.zip {agent_json} recorded (its sha256 differs)"),
    ("truncated", "not the model.zip {agent_json} recorded (its sha256 differs)"),
    ("missing", "missing: the checkpoint {agent_json} needs it"),
    ("no_digest", "{agent_json} records no model_sha256 of it"),
    ("truncated_with_its_digest", "not weights of this run's model: "),
])
def test_a_deep_policy_plays_only_with_the_model_zip_its_checkpoint_recorded(tmp_path, capsys, damage, expected):
    policy = copied(tmp_path)
    model_zip = policy / "model.zip"
    if damage == "another_policys_weights":  # same network shape, another task's training
        shutil.copyfile(SHIPPED / "residual_forward_sac" / "model.zip", model_zip)
    elif damage.startswith("truncated"):
        model_zip.write_bytes(model_zip.read_bytes()[:5000])
        if damage == "truncated_with_its_digest":
            set_digest(policy, hashlib.sha256(model_zip.read_bytes()).hexdigest())
    elif damage == "missing":
        model_zip.unlink()
    else:
        set_digest(policy, None)
    code, out, err = evaluate(capsys, "--run", str(policy), "--episodes", "1", "--horizon-s", "0.2")
    line = one_line(err)
    assert code == 1 and out == "", (code, out)
    assert line.startswith(f"evaluate.py: {model_zip}: "), line
    assert expected.format(agent_json=policy / "agent.json") in line, line
    assert "model.zip.zip" not in line and "weights_only" not in line


@pytest.mark.deep
def test_a_run_caught_between_its_checkpoint_and_the_rename_plays_the_recorded_model(tmp_path, capsys):
    """A trainer writes model.partial.zip, then agent.json with its digest, then renames it model.zip: evaluate.py
    reading in between plays the partial file, the model agent.json names (not the older model.zip)."""
    policy = copied(tmp_path)
    (policy / "model.zip").rename(policy / "model.partial.zip")
    shutil.copyfile(SHIPPED / "residual_forward_sac" / "model.zip", policy / "model.zip")  # the older checkpoint's
    code, out, err = evaluate(capsys, "--run", str(policy), "--episodes", "1", "--horizon-s", "0.2")
    assert code == 0 and json.loads(out.splitlines()[-1])["episodes"] == 1, err
    (policy / "model.partial.zip").unlink()
    code, out, err = evaluate(capsys, "--run", str(policy), "--episodes", "1", "--horizon-s", "0.2")
    assert code == 1 and "not the model.zip" in one_line(err), "the older model alone does not play"


@pytest.mark.deep
def test_the_shipped_deep_policy_with_its_digest_plays(tmp_path, capsys):
    code, out, err = evaluate(capsys, "--run", str(copied(tmp_path)), "--episodes", "1", "--horizon-s", "0.2")
    assert code == 0 and json.loads(out.splitlines()[-1])["episodes"] == 1, err


@pytest.mark.parametrize("args, expected", [
    (["--seed", "-1"], "--seed must be from 0 to 2147483647, got -1"),
    (["--seed", "2147483648"], "--seed must be from 0 to 2147483647, got 2147483648"),
    (["--horizon-s", "inf"], "argument --horizon-s: 'inf' is not a finite number"),
    (["--horizon-s", "1e300"], "--horizon-s must be > 0 and at most 86400 s, got 1e+300"),
    (["--initial-tilt", "nan", "0.1"], "argument --initial-tilt: 'nan' is not a finite number"),
    (["--video", "{tmp_path}"], "--video must name an .mp4 file, got '{tmp_path}'"),
    (["--video", "{tmp_path}/folder.mp4"], "--video: '{tmp_path}/folder.mp4' is a folder, not an .mp4 file"),
])
def test_a_bad_option_of_evaluate_is_one_line(tmp_path, capsys, args, expected):
    (tmp_path / "folder.mp4").mkdir()
    args = [arg.format(tmp_path=tmp_path) for arg in args]
    code, out, err = evaluate(capsys, "--run", str(CUBE_DEMO), "--episodes", "1", *args, tasks=CUBE_TASKS)
    assert code == 2 and out == ""
    assert one_line(err) == f"evaluate.py: error: {expected.format(tmp_path=tmp_path)} (evaluate.py --help lists " \
                            f"the options)"


@pytest.mark.parametrize("speed", ["nan", "inf", "-inf"])
def test_a_speed_that_is_not_finite_is_refused_as_the_speed(capsys, speed):
    code, out, err = evaluate(capsys, "--policy", "controller", "--task", "hop_in_place", f"--speed={speed}",
                              "--episodes", "1", policies=scripted_policies.POLICIES)
    assert code == 2 and out == ""
    assert one_line(err).startswith(f"evaluate.py: error: argument --speed: '{speed}' is not a finite number"), err


@pytest.mark.parametrize("video, expected", [
    ("out.avi", "the video must be an .mp4 file, got 'out.avi'"),
    ("folder.mp4", "the video must be an .mp4 file, got 'folder.mp4' (a folder)"),
])
def test_demo_into_a_video_that_is_not_an_mp4_file_is_one_line(tmp_path, monkeypatch, capsys, video, expected):
    from workspace_tools import cli
    monkeypatch.chdir(tmp_path)
    (tmp_path / "folder.mp4").mkdir()
    monkeypatch.setattr(cli.os, "execvp", lambda *args: pytest.fail(f"{args} ran"))
    assert cli.main(["demo", "cube", video]) == 1
    assert capsys.readouterr().err == f"[ws] error: {expected}\n"


def _umask():
    mask = os.umask(0)
    os.umask(mask)
    return mask


def shipped_files(folder):
    return sorted(p.name for p in folder.iterdir())


def zip_of(entries):
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as archive:
        for name, data in entries.items():
            archive.writestr(name, data)
    return out.getvalue()


@pytest.mark.deep
@pytest.mark.parametrize("damage, expected", [
    ("no_weights_with_its_digest", "not shipped, its policy does not load: "),
    ("not_a_zip_with_its_digest", "not shipped, its policy does not load: "),
    ("another_policys_weights", "not the model.zip"),
])
def test_a_damaged_run_ships_nothing_and_leaves_the_old_policy(tmp_path, damage, expected):
    run = copied(tmp_path)
    model_zip = run / "model.zip"
    if damage == "another_policys_weights":
        shutil.copyfile(SHIPPED / "residual_forward_sac" / "model.zip", model_zip)
    else:
        model_zip.write_bytes(zip_of({"data": "{}"}) if damage.startswith("no_weights") else b"not a zip at all")
        set_digest(run, hashlib.sha256(model_zip.read_bytes()).hexdigest())
    destination = tmp_path / "policies" / "demo"
    shutil.copytree(CUBE_DEMO, destination)
    before = {p.name: p.read_bytes() for p in destination.iterdir()}
    with pytest.raises(ValueError, match=f"^{run}: not shipped") as refused:
        ship_run(run, destination)
    assert expected in str(refused.value) and "\n" not in str(refused.value), refused.value
    assert {p.name: p.read_bytes() for p in destination.iterdir()} == before, "the old policy is left whole"
    assert shipped_files(destination.parent) == ["demo"], "no staging folder left"


@pytest.mark.deep
def test_shipping_over_a_policy_replaces_the_folder_whole(tmp_path):
    destination = tmp_path / "policies" / "demo"
    shutil.copytree(CUBE_DEMO, destination)  # a Q-table policy
    names = ship_run(SHIPPED / "residual_in_place_sac", destination)
    assert shipped_files(destination) == sorted(names) == ["agent.json", "episodes.csv", "learning_curve.png",
                                                           "model.zip", "params.yaml", "summary.json"]
    assert oct(destination.stat().st_mode & 0o777) == oct(0o777 & ~_umask()), "a folder as others of the checkout"
    names = ship_run(CUBE_DEMO, destination)  # and back: no agent.json or model.zip left beside qtable.json
    assert shipped_files(destination) == sorted(names) == sorted(p.name for p in CUBE_DEMO.iterdir())
    assert {p.name: p.read_bytes() for p in destination.iterdir()} == \
        {p.name: p.read_bytes() for p in CUBE_DEMO.iterdir()}
    assert shipped_files(destination.parent) == ["demo"], "no staging folder left"


def test_shipping_is_one_rename_of_a_folder_written_beside_it(tmp_path, monkeypatch):
    """The new folder is written and loaded back beside the destination, then exchanged with the old one in one
    rename: the destination's inode is the staged folder's."""
    from workspace_tools import ship
    destination = tmp_path / "policies" / "demo"
    shutil.copytree(CUBE_DEMO, destination)
    (destination / "model.zip").write_bytes(b"an old deep policy's file")
    staged = []
    swap = ship._swap_in

    def watched(folder, target):
        staged.append((folder.stat().st_ino, sorted(p.name for p in folder.iterdir())))
        assert (target / "model.zip").is_file(), "the old policy is whole until the swap"
        swap(folder, target)
    monkeypatch.setattr(ship, "_swap_in", watched)
    ship_run(CUBE_DEMO, destination)
    assert staged == [(destination.stat().st_ino, shipped_files(destination))]
    assert "model.zip" not in shipped_files(destination)


def test_shipping_onto_a_file_is_refused(tmp_path):
    (tmp_path / "demo").write_text("a file")
    with pytest.raises(ValueError, match="demo: not a folder"):
        ship_run(CUBE_DEMO, tmp_path / "demo")
    assert (tmp_path / "demo").read_text() == "a file"


def strings_in(value):
    """Every string of a JSON or YAML document, keys too."""
    if isinstance(value, dict):
        return [text for key, item in value.items() for text in [*strings_in(key), *strings_in(item)]]
    if isinstance(value, list):
        return [text for item in value for text in strings_in(item)]
    return [value] if isinstance(value, str) else []


def test_no_shipped_policy_names_an_absolute_path():
    """A shipped policy carries no path of the machine it was trained on (agent_config shipped package-relative)."""
    import yaml
    files = sorted(path for path in REPO.glob("*/policies/*/*") if path.suffix in (".json", ".yaml"))
    assert REPO / "hopper_training" / "policies" / "end_to_end" / "agent.json" in files
    for path in files:
        data = json.loads(path.read_text()) if path.suffix == ".json" else yaml.safe_load(path.read_text())
        absolute = [text for text in strings_in(data) if text.startswith(("/", "~")) or text[1:3] == ":\\"]
        assert not absolute, f"{path.relative_to(REPO)} names {absolute}"
    checkpoint = json.loads((SHIPPED / "end_to_end" / "agent.json").read_text())
    assert checkpoint["agent_config"] == "robot_rl/config/bc_dagger.yaml"
    assert (REPO / checkpoint["agent_config"]).is_file(), "the package's file (robot_rl's folder is its package)"


@pytest.mark.parametrize("policy", ["end_to_end", pytest.param("residual_in_place_sac", marks=pytest.mark.deep)])
def test_shipping_writes_agent_config_relative_to_its_package_else_null(tmp_path, policy):
    package = tmp_path / "src" / "my_tuning"  # a ROS package whose folder is not named as it
    (package / "config").mkdir(parents=True)
    (package / "package.xml").write_text("<package format=\"2\">\n  <name>tuned_pkg</name>\n</package>\n")
    outside = tmp_path / "elsewhere.yaml"
    for config, expected in ((package / "config" / "agent.yaml", "tuned_pkg/config/agent.yaml"), (outside, None)):
        run = tmp_path / "run"
        shutil.rmtree(run, ignore_errors=True)
        shutil.copytree(SHIPPED / policy, run)
        for name in ("agent.json", "summary.json"):
            data = json.loads((run / name).read_text())
            (run / name).write_text(json.dumps({**data, "agent_config": str(config)}))
        before = json.loads((run / "agent.json").read_text())
        destination = tmp_path / "policies" / policy
        ship_run(run, destination, list(HOPPER_TASKS))
        for name in ("agent.json", "summary.json"):
            assert json.loads((destination / name).read_text())["agent_config"] == expected, (config, name)
        after = json.loads((destination / "agent.json").read_text())
        assert {k: v for k, v in after.items() if k not in ("agent_config", "model_sha256")} == \
            {k: v for k, v in before.items() if k not in ("agent_config", "model_sha256")}, "nothing else changes"
