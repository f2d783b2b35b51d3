"""robot_rl.cluster's pure parts (the commands it builds, the state it keeps) and the loopback cluster's /proc
reading; the cluster itself runs in test/integration/test_ray_workers.py."""
from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest

from robot_rl import cluster
from workspace_tools.ray_cluster import _address

pytestmark = pytest.mark.ray  # needs Ray (requirements-distributed.txt)


def test_a_head_gets_the_workspace_options(tmp_path):
    command = cluster.ray_start_command(tmp_path / "ray", port=6380, num_cpus=2)
    assert command[command.index("--temp-dir") + 1] == str(tmp_path / "ray" / "r")  # Ray's, inside ours
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
        assert cluster.ray_dir(folder) == folder / "r", "Ray's own folder (which Ray makes 0777) is inside ours"
        command = cluster.ray_start_command(folder)
        assert command[command.index("--temp-dir") + 1] == str(folder / "r")
    finally:
        folder.rmdir()


def test_make_private_sets_every_folder_inside_to_0700(tmp_path):
    (tmp_path / "r" / "session_1" / "sockets").mkdir(parents=True)
    for folder in (tmp_path / "r", tmp_path / "r" / "session_1", tmp_path / "r" / "session_1" / "sockets"):
        folder.chmod(0o777)  # as Ray leaves them
    cluster.make_private(tmp_path)
    assert {stat.S_IMODE(p.stat().st_mode) for p in tmp_path.rglob("*")} == {0o700}


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
    assert "no Ray node of this workspace runs" in cluster.status(tmp_path)
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


def run_main(monkeypatch, capsys, tmp_path, *argv):
    monkeypatch.setenv(cluster.STATE_DIR_ENV, str(tmp_path))
    try:
        code = cluster.main(list(argv))
    except SystemExit as exit_:
        code = exit_.code
    return code, capsys.readouterr()


@pytest.mark.parametrize("argv, expected", [
    (["start", "--port", "99999"], "argument --port: '99999' is not a port from 1 to 65535"),
    (["start", "--port", "0"], "argument --port: '0' is not a port from 1 to 65535"),
    (["start", "--num-cpus", "0"], "argument --num-cpus: '0' is not a number of CPUs (1 or more)"),
    (["join", "nonsense"], "'nonsense' is not a cluster address HOST:PORT (a port from 1 to 65535), e.g. "
                           "192.168.1.10:6379"),
    (["join", "10.0.0.1:70000"], "'10.0.0.1:70000' is not a cluster address HOST:PORT"),
    (["frobnicate"], "argument command: invalid choice: 'frobnicate'"),
])
def test_a_bad_cluster_argument_is_one_line_and_starts_nothing(monkeypatch, capsys, tmp_path, argv, expected):
    (tmp_path / "auth_token").write_text("x" * 64)  # join would need it
    code, output = run_main(monkeypatch, capsys, tmp_path, *argv)
    assert code == 1 and output.out == ""
    assert len(output.err.splitlines()) == 1 and output.err.startswith(f"[ws] error: {expected}"), output.err
    assert not (tmp_path / "node.json").exists() and not (tmp_path / "node.log").exists()


def test_a_second_start_while_one_is_under_way_is_refused_in_one_line(monkeypatch, capsys, tmp_path):
    """The first holds cluster.lock while its node starts; the second finds it held and starts nothing."""
    with cluster.locked(tmp_path):
        try:
            code, output = run_main(monkeypatch, capsys, tmp_path, "start", "--port", "6399")
        finally:
            if (tmp_path / "node.json").exists():  # without the lock: a node started, end it
                record = json.loads((tmp_path / "node.json").read_text())
                cluster.end_node(record["pid"], record["temp_dir"])
        assert code == 1 and output.err == (
            f"[ws] error: another ./ws cluster start, join or stop of this workspace is under way (it holds "
            f"{tmp_path / 'cluster.lock'}): wait for it, then ./ws cluster status\n"), output.err
        assert not (tmp_path / "node.log").exists()
        with pytest.raises(cluster.ClusterError, match="under way"):
            cluster.stop_node(tmp_path)
    assert cluster.stop_node(tmp_path) is None, "the lock is free once its holder let go"


def test_a_node_killed_with_sigkill_is_cleaned_up_by_status_and_stop(tmp_path):
    """A node's `ray start` killed with SIGKILL leaves its temp folder and the processes of its group: status
    (and stop, and the next start) kill those and remove the folder."""
    for command in ("status", "stop"):
        temp_dir = cluster.new_temp_dir()
        (cluster.ray_dir(temp_dir) / "session_1" / "sockets").mkdir(parents=True)
        # a session leader with a child in its group, as ray start and the daemons it leaves
        leader = subprocess.Popen(["sh", "-c", "sleep 600 & echo $!; exec sleep 601"], stdout=subprocess.PIPE,
                                  text=True, start_new_session=True)
        child = int(leader.stdout.readline())
        (tmp_path / "node.json").write_text(json.dumps({"pid": leader.pid, "address": "10.0.0.1:6379", "head": True,
                                                        "temp_dir": str(temp_dir)}))
        leader.kill()
        leader.wait()
        try:
            if command == "status":
                assert cluster.status(tmp_path).startswith(f"the node of 10.0.0.1:6379 (pid {leader.pid}) had died: "
                                                           f"its temp folder {temp_dir} is removed; ")
            else:
                assert cluster.stop_node(tmp_path) is None
            assert not temp_dir.exists() and not (tmp_path / "node.json").exists()
            deadline = time.monotonic() + 10.0
            while Path(f"/proc/{child}").exists() and _state(child) != "Z" and time.monotonic() < deadline:
                time.sleep(0.05)
            assert not Path(f"/proc/{child}").exists() or _state(child) == "Z", "what was left of its group is killed"
        finally:
            try:
                os.killpg(leader.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            shutil.rmtree(temp_dir, ignore_errors=True)


def _state(pid):
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return "gone"


def driver(address, handler):
    """A process that joins `address` as the training node would (cluster.connect), its SIGTERM handler `handler`
    ("record": as the training node's, which only records the stop; "default")."""
    script = f"""
import signal, sys
from robot_rl import cluster
received = []
import ray
joining = ray.init


def announced(*args, **kwargs):  # says when ray.init is under way
    print("joining", flush=True)
    return joining(*args, **kwargs)


ray.init = announced
if {handler!r} == "record":
    signal.signal(signal.SIGTERM, lambda number, frame: received.append(number))
try:
    cluster.connect({address!r})
except cluster.ClusterError as error:
    print(f"ClusterError: {{error}} (handler saw {{received}})", file=sys.stderr)
    sys.exit(1)
"""
    return subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_an_address_where_nothing_listens_is_named_at_once():
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]  # bound, not listening: connections are refused
        process = driver(f"127.0.0.1:{port}", "record")
        start = time.monotonic()
        try:
            _, err = process.communicate(timeout=60)
        finally:
            process.kill()
    assert time.monotonic() - start < 30 and process.returncode == 1
    assert f"ClusterError: no Ray cluster at 127.0.0.1:{port}: nothing accepts connections there (Connection " \
           f"refused): is its head up" in err, err


@pytest.mark.parametrize("handler", ["record", "default"])
def test_sigterm_ends_joining_a_cluster_that_does_not_answer_within_10_s(handler):
    """A port that accepts connections but where Ray finds no GCS (Ray 2.60 connects to the machine's address, not
    127.0.0.1): Ray's own connect retries for minutes with no signal handled; here SIGTERM ends it within 10 s, and
    the process's own handler still sees it."""
    with socket.socket() as silent:
        silent.bind(("127.0.0.1", 0))
        silent.listen(8)
        silent.settimeout(60)
        address = f"127.0.0.1:{silent.getsockname()[1]}"
        process = driver(address, handler)
        connections = []
        try:
            connections.append(silent.accept()[0])  # the probe
            assert process.stdout.readline() == "joining\n"
            process.send_signal(signal.SIGTERM)
            try:
                _, err = process.communicate(timeout=10)
            except subprocess.TimeoutExpired:
                process.kill()
                pytest.fail(f"SIGTERM did not end it within 10 s: {process.communicate()}")
        finally:
            process.kill()
            for connection in connections:
                connection.close()
    if handler == "record":
        assert process.returncode == 1 and f"ClusterError: stopped (SIGTERM) while joining the Ray cluster at " \
            f"{address} (handler saw [15])" in err, err
    else:
        assert process.returncode == -signal.SIGTERM, err
