"""Ship a trained run into the repository (`<package>/policies/<name>/`): its checkpoint and results, and for a
deep run its weights only.

A run folder holds the checkpoint (tabular: qtable.json; deep: agent.json and SB3's model.zip, a bc_dagger
run's agent.json with its student.npz and student.json, or agent rllib_ppo's agent.json with its numpy weights
rllib_module.npz), params.yaml, episodes.csv, learning_curve.png and summary.json. Shipped, SB3's model.zip keeps
only its torch tensors (the *.pth entries, read with torch's weights_only by SB3's set_parameters) and its version:
SB3's `data` entry (JSON with cloudpickled objects, which evaluate.py never reads) and system_info.txt are left
out, and agent.json's model_sha256 is that of the new file. A bc_dagger student and an rllib_ppo module are weights
only already (numpy arrays and JSON numbers): their files are copied as they are, and agent.json's weights_sha256
still names them (checked again when the policy loads). evaluate.py --run, ./ws demo and resume read a shipped
policy as the run, but for a bc_dagger student: its aggregate data stays with the run, and its agent.json ships
without what only a resume reads (that file's record, the RNG states). The run's `agent_config` (in agent.json
and summary.json: the agent's params file, absolute on the machine that trained) ships as `<package>/<path in the
package>` when the file lies in a ROS package (a folder with a package.xml: `robot_rl/config/bc_dagger.yaml`),
else as null (agent.json's `agent_params` holds its values): a shipped policy names no path of the machine it was
trained on.

A tabular run whose greedy table was checked during training (robot_rl.agents.qlearn.selection) ships the table the
checks kept when RUN is its qtable_best.json: that file as the policy's qtable.json (its `selected` entry says which
check kept it), beside the run's results and its selection.csv.

Nothing ships that evaluate.py would not play: the run is loaded as evaluate.py loads it (a deep run's model.zip
must be the one its agent.json recorded), the policy is written to a folder of its own beside the destination and
loaded back from there (a deep policy's weights into the model rebuilt on the task's env), and only then does that
folder take the destination's place: in one rename (renameat2's RENAME_EXCHANGE; two renames where the file system
cannot), so a reader sees the old policy or the new one, never files of both, and a failure leaves the old one.
"""
from __future__ import annotations

import ctypes
import errno
import hashlib
import importlib
import json
import os
import re
import shutil
import tempfile
import zipfile
from collections.abc import Sequence
from io import BytesIO
from pathlib import Path
from typing import Any

from hopper_training.teacher.student import ARCHITECTURE_FILE, CHECKPOINT_FORMAT, RESUME_ENTRIES, WEIGHTS_FILE
from robot_rl import RunFileError, TaskSpec, TrainedRun, make_env, write_bytes_atomic, write_json_atomic
from robot_rl.agents.qlearn.selection import BEST_CHECKPOINT, SELECTION_CSV
from workspace_tools.robots import ROBOTS

SUMMARY = "summary.json"
RESULTS = ("params.yaml", "episodes.csv", "learning_curve.png", SUMMARY)
TABULAR_CHECKPOINT, DEEP_CHECKPOINT, MODEL = "qtable.json", "agent.json", "model.zip"
RLLIB_WEIGHTS = "rllib_module.npz"  # agent rllib_ppo's weights (numpy arrays; agent.json records their sha256)
KEPT_ENTRIES = ("_stable_baselines3_version",)  # besides every *.pth
RENAME_EXCHANGE, AT_FDCWD = 2, -100  # linux/fs.h, fcntl.h
STUDENT_FILES = (WEIGHTS_FILE, ARCHITECTURE_FILE)  # a bc_dagger run's weights (hopper_training.teacher.student)


def shipped_agent_config(value: Any) -> str | None:
    """A run's `agent_config` as it ships: `<package>/<path in the package>` for a file in a ROS package (the
    nearest folder above it with a package.xml names the package), a relative one (shipped already) as it is, else
    None (an absolute path outside any package, or none)."""
    if not isinstance(value, str) or not value:
        return None
    path = Path(value)
    if not path.is_absolute():
        return None if ".." in path.parts else path.as_posix()
    for folder in path.parents:
        manifest = folder / "package.xml"
        if manifest.is_file():
            try:
                name = re.search(r"<name>\s*([^<\s]+)\s*</name>", manifest.read_text(encoding="utf-8"))
            except (OSError, UnicodeDecodeError):
                name = None
            return f"{name.group(1) if name else folder.name}/{path.relative_to(folder).as_posix()}"
    return None


def _copy_json(source: Path, target: Path, leave_out: Sequence[str] = ()) -> dict[str, Any]:
    """Copy a run's JSON file without the entries `leave_out` names, its `agent_config` as shipped
    (shipped_agent_config); the file's bytes as they are when that changes nothing. Returns its contents as
    written."""
    text = source.read_text(encoding="utf-8")
    try:
        data = json.loads(text)
    except ValueError as error:
        raise ValueError(f"{source}: not JSON ({error})") from None
    if not isinstance(data, dict):
        shutil.copyfile(source, target)
        return {}
    shipped = {key: value for key, value in data.items() if key not in leave_out}
    if "agent_config" in shipped:
        shipped["agent_config"] = shipped_agent_config(shipped["agent_config"])
    if shipped == data:
        shutil.copyfile(source, target)
    else:
        write_json_atomic(target, shipped)
    return shipped


def weights_only(model_zip: bytes, source: Path) -> bytes:
    """SB3's model.zip with only its torch tensors (*.pth) and its version entry, in their order."""
    out = BytesIO()
    try:
        with zipfile.ZipFile(BytesIO(model_zip)) as source_zip, \
                zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as target:
            for entry in source_zip.infolist():
                if entry.filename.endswith(".pth") or entry.filename in KEPT_ENTRIES:
                    target.writestr(entry.filename, source_zip.read(entry))
    except (zipfile.BadZipFile, zipfile.LargeZipFile, EOFError) as error:
        raise ValueError(f"{source}: not a model.zip SB3 wrote ({error})") from None
    return out.getvalue()


def all_tasks() -> list[TaskSpec[Any]]:
    """Every task of every robot ./ws knows (a run's checkpoint names its task)."""
    return [task for robot in ROBOTS.values() for task in importlib.import_module(robot.package).TASKS]


def load_back(checkpoint: Path, tasks: Sequence[TaskSpec[Any]]) -> TrainedRun:
    """The run of `checkpoint` as evaluate.py loads it, its policy built on the task's env (a deep policy's weights
    loaded into its model) and asked for one action; ValueError (or RunFileError) if it cannot be."""
    run = TrainedRun(checkpoint, tasks)
    env = make_env(run.task, params=run.params, backend="direct", seed=0)
    try:
        observation, _ = env.reset(seed=0)
        run.policy(env, 0)(observation)
    finally:
        env.close()
    return run


def ship_run(run: Path, destination: Path, tasks: Sequence[TaskSpec[Any]] | None = None) -> list[str]:
    """Ship run (a run folder or its `latest` link, or a tabular run's qtable_best.json) as the folder destination,
    replacing whatever policy was there in one rename; returns the names written. ValueError for a folder that is not
    a finished run, or a policy that does not load (as evaluate.py would load it) from the run or from what would be
    shipped; nothing changes then."""
    run = run.resolve()
    kept = run.name == BEST_CHECKPOINT and run.is_file()  # the table the checks kept, not the run's last
    if kept:
        run = run.parent
    missing = [name for name in (*RESULTS, *([SELECTION_CSV] if kept else [])) if not (run / name).is_file()]
    if missing:
        raise ValueError(f"{run}: not a run folder (missing {', '.join(missing)})")
    deep = not kept and (run / DEEP_CHECKPOINT).is_file()
    if not deep and not (run / TABULAR_CHECKPOINT).is_file():
        raise ValueError(f"{run}: no checkpoint ({TABULAR_CHECKPOINT} or {DEEP_CHECKPOINT})")
    weights = _weight_files(run) if deep else []
    if destination.is_symlink() or destination.exists() and not destination.is_dir():
        raise ValueError(f"{destination}: not a folder (a policy is shipped as a folder of its own)")
    tasks = all_tasks() if tasks is None else tasks
    checkpoint_name = DEEP_CHECKPOINT if deep else TABULAR_CHECKPOINT
    try:
        load_back(run / (BEST_CHECKPOINT if kept else checkpoint_name), tasks)
    except (RunFileError, ValueError) as error:
        raise ValueError(f"{run}: not shipped, its policy does not load: {error}") from None
    destination.parent.mkdir(parents=True, exist_ok=True)
    staged = Path(tempfile.mkdtemp(prefix=f".{destination.name}.shipping-", dir=destination.parent))
    try:
        names = _write(run, staged, deep, weights, kept)
        try:
            load_back(staged / checkpoint_name, tasks)
        except (RunFileError, ValueError) as error:
            raise ValueError(f"{run}: not shipped, the policy written from it does not load back: {error}") from None
        staged.chmod(0o777 & ~_umask())  # mkdtemp's 0700 -> a folder as any other of the checkout
        _swap_in(staged, destination)
    finally:
        shutil.rmtree(staged, ignore_errors=True)  # the old policy after a swap; the new one after a failure
    return names


def _weight_files(run: Path) -> list[str]:
    """The files beside a deep run's agent.json that hold its weights: SB3's model.zip, a bc_dagger student's or
    rllib_ppo's rllib_module.npz."""
    try:
        checkpoint = json.loads((run / DEEP_CHECKPOINT).read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        raise ValueError(f"{run / DEEP_CHECKPOINT}: not a checkpoint ({error})") from None
    student = isinstance(checkpoint, dict) and checkpoint.get("format") == CHECKPOINT_FORMAT
    rllib = not student and not (run / MODEL).is_file() and (run / RLLIB_WEIGHTS).is_file()
    names = list(STUDENT_FILES) if student else [RLLIB_WEIGHTS] if rllib else [MODEL]
    missing = [name for name in names if not (run / name).is_file()]
    if missing:
        raise ValueError(f"{run}: {DEEP_CHECKPOINT} without its {', '.join(missing)}")
    return names


def _write(run: Path, folder: Path, deep: bool, weights: Sequence[str], kept: bool = False) -> list[str]:
    for name in RESULTS:
        if name == SUMMARY:
            _copy_json(run / name, folder / name)
        else:
            shutil.copyfile(run / name, folder / name)
    if kept:
        shutil.copyfile(run / BEST_CHECKPOINT, folder / TABULAR_CHECKPOINT)
        shutil.copyfile(run / SELECTION_CSV, folder / SELECTION_CSV)
        return [*RESULTS, TABULAR_CHECKPOINT, SELECTION_CSV]
    if not deep:
        shutil.copyfile(run / TABULAR_CHECKPOINT, folder / TABULAR_CHECKPOINT)
        return [*RESULTS, TABULAR_CHECKPOINT]
    student = WEIGHTS_FILE in weights  # a bc_dagger student ships without its data file: no resume state
    checkpoint = _copy_json(run / DEEP_CHECKPOINT, folder / DEEP_CHECKPOINT, RESUME_ENTRIES if student else ())
    if MODEL not in weights:  # a bc_dagger student or rllib_ppo's module: weights only as trained
        for name in weights:
            shutil.copyfile(run / name, folder / name)
        return [*RESULTS, DEEP_CHECKPOINT, *weights]
    model = weights_only((run / MODEL).read_bytes(), run / MODEL)
    checkpoint["model_sha256"] = hashlib.sha256(model).hexdigest()
    write_bytes_atomic(folder / MODEL, model)
    write_json_atomic(folder / DEEP_CHECKPOINT, checkpoint)
    return [*RESULTS, DEEP_CHECKPOINT, MODEL]


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _swap_in(staged: Path, destination: Path) -> None:
    """`staged` becomes `destination`; an old `destination` becomes `staged` (for the caller to remove)."""
    if not destination.exists():
        staged.rename(destination)
        return
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.renameat2(AT_FDCWD, os.fsencode(staged), AT_FDCWD, os.fsencode(destination), RENAME_EXCHANGE) == 0:
        return
    code = ctypes.get_errno()
    if code not in (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP):
        raise OSError(code, os.strerror(code), str(destination))
    old = Path(tempfile.mkdtemp(prefix=f".{destination.name}.old-", dir=destination.parent))
    destination.rename(old / destination.name)  # a file system without RENAME_EXCHANGE: two renames
    staged.rename(destination)
    (old / destination.name).rename(staged)
    old.rmdir()
