"""./ws cluster's faults on real Ray nodes of this machine (issue 42): two starts at once make one node, every temp
folder of ours and Ray's is private (the ./ws cluster node's, the tests' LoopbackCluster's, the sweep's local Ray),
and a node killed with SIGKILL is cleaned up by the next ./ws cluster status."""
import os
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

from robot_rl import cluster, free_port
from workspace_tools.processes import group_members
from workspace_tools.ray_cluster import LoopbackCluster

pytestmark = pytest.mark.ray  # needs Ray (requirements-distributed.txt)


def cluster_command(state, *args):
    return subprocess.Popen([sys.executable, "-m", "robot_rl.workers.cluster", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env={**os.environ, cluster.STATE_DIR_ENV: str(state)})


def mode(path):
    return stat.S_IMODE(path.lstat().st_mode)


def folders(root):
    return [root, *(path for path in root.rglob("*") if path.is_dir() and not path.is_symlink())]


def open_to_others(root):
    """The folders under `root` in which another user could create, remove or replace a file (a socket): writable
    and searchable by others, in a folder every one of whose parents others can search."""
    def searchable(path):
        return all(mode(parent) & stat.S_IXOTH for parent in [path, *path.parents])
    return [str(path) for path in folders(root) if mode(path) & stat.S_IWOTH and searchable(path)]


def assert_private(root, every_folder=True):
    assert root.owner() == Path.home().owner() or root.stat().st_uid == os.getuid()
    assert mode(root) == 0o700, oct(mode(root))
    assert (root / "r").is_dir(), "Ray's temp folder is inside ours"
    if every_folder:
        assert {oct(mode(path)) for path in folders(root)} == {oct(0o700)}, \
            sorted((oct(mode(path)), str(path)) for path in folders(root) if mode(path) != 0o700)
    assert open_to_others(root) == []


def wait_until(condition, timeout, what):
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, what
        time.sleep(0.1)


def test_two_starts_at_once_make_one_private_node_and_a_sigkilled_one_is_cleaned_by_status(tmp_path):
    port = free_port()
    starts = [cluster_command(tmp_path, "start", "--port", str(port), "--num-cpus", "1") for _ in range(2)]
    outputs = [process.communicate(timeout=240) for process in starts]
    record = cluster.read_record(tmp_path)
    try:
        codes = sorted(process.returncode for process in starts)
        refused = next(err for process, (_, err) in zip(starts, outputs) if process.returncode == 1)
        assert codes == [0, 1], outputs
        assert len(refused.splitlines()) == 1 and refused.startswith("[ws] error: "), refused
        assert "is under way" in refused or "runs already" in refused, refused
        assert record is not None and record.address.endswith(f":{port}")
        assert len(list(Path("/tmp").glob("rrl-ray-*"))) >= 1
        root = Path(record.temp_dir)
        assert_private(root)
        sockets = [path for path in (root / "r").rglob("sockets") if path.is_dir()]
        assert sockets and all(mode(path) == 0o700 for path in sockets)
        os.kill(record.pid, signal.SIGKILL)  # the node's `ray start`, as kill -9 of the Ray node
        wait_until(lambda: not cluster._is_node(record), 10, "the killed node's ray start is gone")
        out, err = cluster_command(tmp_path, "status").communicate(timeout=120)
        assert out.startswith(f"the node of {record.address} (pid {record.pid}) had died: its temp folder {root} is "
                              f"removed; no Ray node of this workspace runs"), (out, err)
        assert not root.exists() and not (tmp_path / "node.json").exists()
        wait_until(lambda: not group_members(record.pid), 10, "what was left of the node's group is killed")
    finally:
        if record is not None:
            try:
                os.killpg(record.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            cluster.end_node(record.pid, record.temp_dir, timeout=5)


def test_the_loopback_clusters_temp_folders_are_private(tmp_path):
    with LoopbackCluster(tmp_path, nodes=1) as nodes:
        for root in nodes.temp_dirs:
            assert_private(root)
        nodes.connect()  # a driver: Ray makes the session's folders 0777 again, inside our 0700 folder
        for root in nodes.temp_dirs:
            assert_private(root, every_folder=False)
        nodes.disconnect()
        assert nodes.close() == []
    assert not any(root.exists() for root in nodes.temp_dirs)


def test_the_sweeps_local_ray_temp_folder_is_private():
    import ray

    from workspace_tools import sweep
    root = cluster.new_temp_dir()
    try:
        sweep._start_ray(SimpleNamespace(cluster="", concurrent=1), root)
        assert_private(root)
    finally:
        ray.shutdown()
        import shutil
        shutil.rmtree(root, ignore_errors=True)
