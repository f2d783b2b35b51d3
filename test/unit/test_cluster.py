"""robot_rl.cluster's pure parts (the commands it builds, the state it keeps) and the loopback cluster's /proc
reading; the cluster itself runs in test/integration/test_ray_workers.py."""
from __future__ import annotations

import json
import os
import stat

import pytest

from robot_rl import cluster
from workspace_tools.ray_cluster import _address

pytestmark = pytest.mark.ray  # needs Ray (requirements-distributed.txt)


def test_a_head_gets_the_workspace_options(tmp_path):
    command = cluster.ray_start_command(tmp_path / "ray", port=6380, num_cpus=2)
    assert command[command.index("--temp-dir") + 1] == str(tmp_path / "ray")
    assert {"--block", "--head", "--include-dashboard=false", "--disable-usage-stats"} <= set(command)
    assert command[command.index("--port") + 1] == "6380" and command[command.index("--num-cpus") + 1] == "2"
    assert int(command[command.index("--object-store-memory") + 1]) == cluster.OBJECT_STORE_BYTES


def test_a_joining_node_names_the_head_and_no_head_option(tmp_path):
    command = cluster.ray_start_command(tmp_path, address="10.0.0.1:6379", extra=["--node-ip-address", "10.0.0.2"])
    assert command[command.index("--address") + 1] == "10.0.0.1:6379"
    assert not {"--head", "--port", "--include-dashboard=false"} & set(command)
    assert command[-2:] == ["--node-ip-address", "10.0.0.2"]


def test_the_environment_turns_on_the_token_and_off_the_statistics(tmp_path):
    env = cluster.ray_environment(tmp_path / "auth_token", {"PATH": "/bin"})
    assert env == {"PATH": "/bin", "RAY_USAGE_STATS_ENABLED": "0", "RAY_AUTH_MODE": "token",
                   "RAY_AUTH_TOKEN_PATH": str(tmp_path / "auth_token")}


def test_the_token_is_private_and_kept(tmp_path):
    path = tmp_path / "cluster" / "auth_token"
    cluster.ensure_token(path)
    token = path.read_text()
    assert len(token) == 64 and stat.S_IMODE(path.stat().st_mode) == 0o600
    cluster.ensure_token(path)
    assert path.read_text() == token


def test_the_temp_folder_is_short_and_private():
    folder = cluster.new_temp_dir()
    try:
        assert len(str(folder)) <= 24 and stat.S_IMODE(folder.stat().st_mode) == 0o700
    finally:
        folder.rmdir()


def test_a_driver_takes_an_address_or_this_workspaces_node(tmp_path):
    assert cluster.driver_address("10.0.0.1:6379", tmp_path) == "10.0.0.1:6379"
    with pytest.raises(cluster.ClusterError, match="neither 'ray' nor an address"):
        cluster.driver_address("somewhere", tmp_path)
    with pytest.raises(cluster.ClusterError, match="./ws cluster start"):
        cluster.driver_address("ray", tmp_path)


def test_a_record_of_a_node_that_is_gone_is_dropped(tmp_path):
    record = tmp_path / "node.json"
    record.write_text(json.dumps({"pid": os.getpid(), "address": "10.0.0.1:6379", "head": True,
                                  "temp_dir": "/tmp/rrl-ray-none"}))  # this pid is not that node's ray start
    assert cluster.read_record(tmp_path) is None
    assert not record.exists()


def test_the_state_folder_comes_from_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv(cluster.STATE_DIR_ENV, str(tmp_path))
    assert cluster.state_dir() == tmp_path
    monkeypatch.delenv(cluster.STATE_DIR_ENV)
    with pytest.raises(cluster.ClusterError, match="./ws cluster"):
        cluster.state_dir()


@pytest.mark.parametrize("text,width,expected", [("0100007F", 8, "127.0.0.1"), ("020200C0", 8, "192.0.2.2"),
                                                 ("00000000000000000000000000000000", 32, "::"),
                                                 ("0000000000000000FFFF00000100007F", 32, "127.0.0.1")])
def test_proc_net_addresses_read_as_text(text, width, expected):
    assert _address(text, width) == expected
