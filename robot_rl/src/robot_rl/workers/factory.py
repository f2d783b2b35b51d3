"""Env workers by where they run: processes on this machine (pipes), or Ray actors on a cluster."""
from __future__ import annotations

import importlib
from typing import Any

from ..task import TaskSpec
from .pipe import EnvWorkers

# Imported when asked for: the Ray actors import ray, and the cluster module (which prepares this process to be
# a Ray driver before ray is imported) runs as `python -m robot_rl.workers.cluster`, so no import of robot_rl
# may load it first.
RAY_DRIVER = "robot_rl.workers.cluster:prepare_driver"
RAY_WORKERS = "robot_rl.workers.ray_actors:RayEnvWorkers"


def _resolve(reference: str) -> Any:
    module, _, attr = reference.partition(":")
    return getattr(importlib.import_module(module), attr)


def make_env_workers(task: TaskSpec[Any], n: int, cluster: str | None = None, **kwargs: Any) -> EnvWorkers:
    """N env workers: processes on this machine (cluster None or ""), or Ray actors on `cluster` ("ray": this
    workspace's Ray node, or a cluster's address; robot_rl.workers.ray_actors). The same seeds, order and replies."""
    if not cluster:
        return EnvWorkers(task, n, **kwargs)
    _resolve(RAY_DRIVER)()  # before ray is imported
    ray_workers: type[EnvWorkers] = _resolve(RAY_WORKERS)
    return ray_workers(task, n, cluster=cluster, **kwargs)
