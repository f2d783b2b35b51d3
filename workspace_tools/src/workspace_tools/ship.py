"""Ship a trained run into the repository (`<package>/policies/<name>/`): its checkpoint and results, and for a
deep run a model.zip of the weights only.

A run folder holds the checkpoint (tabular: qtable.json; deep: agent.json and SB3's model.zip), params.yaml,
episodes.csv, learning_curve.png and summary.json. Shipped, SB3's model.zip keeps only its torch tensors (the
*.pth entries, read with torch's weights_only by SB3's set_parameters) and its version: SB3's `data` entry
(JSON with cloudpickled objects, which evaluate.py never reads) and system_info.txt are left out, and
agent.json's model_sha256 is that of the new file. evaluate.py --run, ./ws demo and resume read it as the run.
"""
from __future__ import annotations

import hashlib
import json
import shutil
import zipfile
from io import BytesIO
from pathlib import Path

from robot_rl import write_bytes_atomic, write_json_atomic

RESULTS = ("params.yaml", "episodes.csv", "learning_curve.png", "summary.json")
TABULAR_CHECKPOINT, DEEP_CHECKPOINT, MODEL = "qtable.json", "agent.json", "model.zip"
KEPT_ENTRIES = ("_stable_baselines3_version",)  # besides every *.pth


def weights_only(model_zip: bytes) -> bytes:
    """SB3's model.zip with only its torch tensors (*.pth) and its version entry, in their order."""
    out = BytesIO()
    with zipfile.ZipFile(BytesIO(model_zip)) as source, zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as target:
        for entry in source.infolist():
            if entry.filename.endswith(".pth") or entry.filename in KEPT_ENTRIES:
                target.writestr(entry.filename, source.read(entry))
    return out.getvalue()


def ship_run(run: Path, destination: Path) -> list[str]:
    """Copy run (a run folder or its `latest` link) to destination (created, or emptied of these files);
    returns the names written. ValueError for a folder that is not a finished run."""
    run = run.resolve()
    missing = [name for name in RESULTS if not (run / name).is_file()]
    if missing:
        raise ValueError(f"{run}: not a run folder (missing {', '.join(missing)})")
    deep = (run / DEEP_CHECKPOINT).is_file()
    if not deep and not (run / TABULAR_CHECKPOINT).is_file():
        raise ValueError(f"{run}: no checkpoint ({TABULAR_CHECKPOINT} or {DEEP_CHECKPOINT})")
    if deep and not (run / MODEL).is_file():
        raise ValueError(f"{run}: {DEEP_CHECKPOINT} without its {MODEL}")
    destination.mkdir(parents=True, exist_ok=True)
    for name in RESULTS:
        shutil.copyfile(run / name, destination / name)
    if not deep:
        shutil.copyfile(run / TABULAR_CHECKPOINT, destination / TABULAR_CHECKPOINT)
        return [*RESULTS, TABULAR_CHECKPOINT]
    model = weights_only((run / MODEL).read_bytes())
    checkpoint = json.loads((run / DEEP_CHECKPOINT).read_text())
    checkpoint["model_sha256"] = hashlib.sha256(model).hexdigest()
    write_bytes_atomic(destination / MODEL, model)
    write_json_atomic(destination / DEEP_CHECKPOINT, checkpoint)
    return [*RESULTS, DEEP_CHECKPOINT, MODEL]
