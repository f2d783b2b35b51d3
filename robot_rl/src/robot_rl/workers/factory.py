"""Env workers by where they run: processes on this machine (pipes), or Ray actors on a cluster."""
from __future__ import annotations

import importlib
from typing import Any

from ..task import TaskSpec
from .cluster import prepare_driver
from .pipe import EnvWorkers

RAY_WORKERS = "robot_rl.workers.ray_actors:RayEnvWorkers"  # imported when asked for: it imports ray


def make_env_workers(task: TaskSpec[Any], n: int, cluster: str | None = None, **kwargs: Any) -> EnvWorkers:
    """N env workers: processes on this machine (cluster None or ""), or Ray actors on `cluster` ("ray": this
    workspace's Ray node, or a cluster's address; robot_rl.workers.ray_actors). The same seeds, order and replies."""
    if not cluster:
        return EnvWorkers(task, n, **kwargs)
    prepare_driver()  # before ray is imported
    module, _, attr = RAY_WORKERS.partition(":")
    ray_workers: type[EnvWorkers] = getattr(importlib.import_module(module), attr)
    return ray_workers(task, n, cluster=cluster, **kwargs)
