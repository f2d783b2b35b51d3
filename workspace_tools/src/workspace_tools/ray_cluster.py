"""A Ray cluster of several nodes on this one machine, for the tests and the benchmark.

`LoopbackCluster(folder, nodes=2)` starts a head (`ray start --head --block`) and nodes - 1 nodes joining it
(`ray start --address ... --block`), each in a session of its own with a Ray temp folder of its own and
`cpus_per_node` CPUs (the head `head_cpus` if given), with robot_rl.workers.cluster's options (no dashboard, no usage
statistics, a small object store, a token: one per process, TOKEN, as Ray reads a driver's once). Every node
carries a mark in its environment, which every process it starts inherits (Ray's daemons, its workers and what
they start: env workers' masters and sim nodes), so `processes()` finds them all. `connect()` makes this
process the cluster's driver (until `disconnect()`); `kill_node(i)` kills node i at once, as a machine lost
(or its raylet crashed); each node's temp folder is private as `./ws cluster`'s (robot_rl.workers.cluster: mode
0700, Ray's folders inside it 0700 once it is up); close() ends each node by its PID (SIGTERM, then SIGKILL to
its process group), kills whatever still carries the mark and returns those pids (none, when all ended
cleanly). Use it as a context manager.

Ray 2.60 does not put a node on 127.0.0.1: it advertises the machine's address and its servers listen on
every interface (robot_rl.workers.cluster); `listening_sockets()` says where each process of the cluster listens.
"""
from __future__ import annotations

import ipaddress
import os
import secrets
import signal
import subprocess
import time
import uuid
from pathlib import Path
from types import TracebackType
from typing import Any

from robot_rl import cluster as ray_cluster
from workspace_tools.launch_reaper import processes_with

MARK_VARIABLE = "ROBOT_RL_RAY_TEST_CLUSTER"
# One token for every cluster this process starts: Ray reads a driver's token once per process.
TOKEN = secrets.token_hex(32)
KILL_WAIT = 10.0  # s for killed processes to be gone


class LoopbackCluster:
    """Ray nodes on this machine (see the module docstring)."""

    def __init__(self, folder: Path, nodes: int = 2, cpus_per_node: int = 1, head_cpus: int | None = None):
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.mark = uuid.uuid4().hex
        self.token = ray_cluster.token_path(self.folder)
        self.token.write_text(TOKEN)
        self.token.chmod(0o600)
        (self.folder / "tmp").mkdir(exist_ok=True)  # the workers' temporary folders (a killed one leaves its own)
        self.env = ray_cluster.ray_environment(self.token, {**os.environ, MARK_VARIABLE: self.mark,
                                                            "TMPDIR": str(self.folder / "tmp")})
        self.processes_started: list[subprocess.Popen[bytes]] = []
        self.temp_dirs: list[Path] = []
        self.address = ""
        self.connected = False
        try:
            for i in range(nodes):
                self._start_node(i, head_cpus if i == 0 and head_cpus is not None else cpus_per_node)
        except BaseException:
            self.close()
            raise

    def _start_node(self, i: int, cpus: int) -> None:
        temp_dir = ray_cluster.new_temp_dir()
        self.temp_dirs.append(temp_dir)
        log = self.folder / f"node{i}.log"
        # port 0: a free one, so that tests side by side never meet
        command = ray_cluster.ray_start_command(temp_dir, self.address or None, port=0, num_cpus=cpus)
        with open(log, "wb") as output:
            process = subprocess.Popen(command, env=self.env, stdin=subprocess.DEVNULL, stdout=output,
                                       stderr=subprocess.STDOUT, start_new_session=True)
        self.processes_started.append(process)
        ray_cluster.wait_started(process, log)
        ray_cluster.make_private(temp_dir)
        if not self.address:
            self.address = ray_cluster.head_address(temp_dir)

    @property
    def driver_environment(self) -> dict[str, str]:
        """What a driver's environment needs to join the cluster (its token)."""
        return ray_cluster.ray_environment(self.token, {})

    def connect(self, **init_kwargs: Any) -> None:
        """Make this process the cluster's driver (ray.init); close() disconnects it."""
        os.environ.update(self.driver_environment)
        import ray
        ray.init(address=self.address, **{"log_to_driver": False, "logging_level": "WARNING", **init_kwargs})
        self.connected = True

    def disconnect(self) -> None:
        """End this process's connection (ray.shutdown), if connect() made it."""
        if self.connected:
            import ray
            ray.shutdown()
            self.connected = False

    def processes(self) -> list[int]:
        """Pids of every live process of the cluster (the nodes and everything they started)."""
        return processes_with(MARK_VARIABLE, self.mark)

    def kill_node(self, i: int, machine: bool = True) -> None:
        """SIGKILL node i at once. `machine`: every process of its session (Ray's, its workers and what they
        started), as a machine lost; else its process group only (its `ray start`, raylet and daemons, as a
        raylet crash), whose workers, each in a process group of its own, end once they find their raylet gone."""
        leader = self.processes_started[i].pid
        for pid in [pid for pid in self.processes() if _session(pid) == leader] if machine else []:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        try:
            os.killpg(leader, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.processes_started[i].wait(KILL_WAIT)

    def close(self) -> list[int]:
        """Disconnect, end every node by its PID, then kill what is left of the cluster; returns those pids."""
        self.disconnect()
        for process, temp_dir in reversed(list(zip(self.processes_started, self.temp_dirs))):
            ray_cluster.end_node(process.pid, temp_dir)
        left = self.processes()
        for pid in left:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        deadline = time.monotonic() + KILL_WAIT
        while self.processes() and time.monotonic() < deadline:
            time.sleep(0.1)
        return left

    def __enter__(self) -> LoopbackCluster:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.close()


def _session(pid: int) -> int:
    """The session id of `pid` (0 when it is gone)."""
    try:
        return int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[3])
    except OSError:
        return 0


def listening_sockets(pids: list[int]) -> dict[int, list[tuple[str, int]]]:
    """Per pid, the (address, port) of every TCP socket it listens on (IPv4 and IPv6; from /proc)."""
    listening: dict[str, tuple[str, int]] = {}  # socket inode -> address
    for table, width in (("tcp", 8), ("tcp6", 32)):
        for line in Path(f"/proc/net/{table}").read_text().splitlines()[1:]:
            fields = line.split()
            if fields[3] == "0A":  # LISTEN
                address, port = fields[1].split(":")
                listening[fields[9]] = (_address(address, width), int(port, 16))
    found: dict[int, list[tuple[str, int]]] = {}
    for pid in pids:
        try:
            links = [os.readlink(f"/proc/{pid}/fd/{fd}") for fd in os.listdir(f"/proc/{pid}/fd")]
        except OSError:  # gone
            continue
        inodes = [link[len("socket:["):-1] for link in links if link.startswith("socket:[")]
        found[pid] = [listening[inode] for inode in inodes if inode in listening]
    return found


def _address(hex_address: str, width: int) -> str:
    """/proc/net/tcp's address (little-endian 32-bit words in hex) as text; an IPv4-mapped IPv6 one as IPv4."""
    raw = b"".join(bytes.fromhex(hex_address[i:i + 8])[::-1] for i in range(0, width, 8))
    address = ipaddress.ip_address(raw)
    mapped = getattr(address, "ipv4_mapped", None)
    return str(mapped or address)


def process_name(pid: int) -> str:
    """The command line of `pid` (empty when it is gone)."""
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace").strip()
    except OSError:
        return ""
