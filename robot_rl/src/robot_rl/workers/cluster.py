"""A Ray cluster for the workspace (`./ws cluster start|join ADDRESS|stop|status`) and how a driver joins it.

Each machine runs one Ray node, started as `ray start --block` in a session of its own inside the workspace
environment (./ws runs this module there), so every Ray worker it starts has ROS, the devel space and the
workspace's venv on its path: an env worker there can start its private master and sim node. A node's files
are in a state folder (ROBOT_RL_CLUSTER_DIR, which ./ws sets to .ws/cluster): node.json (its pid, address,
role and Ray temp folder), node.log (ray start's output), auth_token, and cluster.lock: start, join and stop take
it (flock) for as long as they run, so a second one at once is refused with one line instead of starting a Ray
node that node.json does not know of; status takes it to clean up. A node found dead (its `ray start` killed
with SIGKILL) is cleaned up by the next start, join, stop or status: what is left of its process group is
killed and its temp folder removed.

What every node gets: usage statistics off, no dashboard, a small object store (env messages are tiny),
Ray's temp folder short (a unix socket path holds at most 107 bytes) and private: Ray makes each of its folders
0777 (ray._common.utils.try_make_directory_shared), so its temp folder is `r` inside a folder of ours of mode 0700
(new_temp_dir, its own per node), which no other user can enter, and its folders are set to 0700 once it is up
(make_private); and token authentication (RAY_AUTH_MODE=token, the token in auth_token, mode 0600): Ray 2.60
advertises the machine's address even when given 127.0.0.1 and its servers listen on every interface, so a
token is what keeps others out. A machine that joins needs the head's auth_token in its own state folder.
stop() ends the node by the pid it recorded (SIGTERM: Ray drains and ends what it started, then SIGKILL to
its process group), never by a process name, so other clusters on the machine are left alone.

A driver (the training node with cluster:=..., a sweep) calls `connect(cluster)`: "ray" is this
workspace's node (started or joined with ./ws cluster), anything else the ADDRESS (HOST:PORT) of a cluster
this machine has joined (a driver talks to its own machine's node). It is bounded: the address's port must
accept a TCP connection within PROBE_TIMEOUT (else one line naming the address, at once), then ray.init runs
in a thread while this one waits at most CONNECT_TIMEOUT, SIGTERM and SIGINT ending the wait at once (Ray's
own connect loop retries for many minutes and lets no signal handler run).
"""
from __future__ import annotations

import argparse
import contextlib
import json
import logging
import os
import re
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from ..atomic import lock_while

STATE_DIR_ENV = "ROBOT_RL_CLUSTER_DIR"
DEFAULT_PORT = 6379              # the head's GCS port (Ray's own default): the one port a joining machine names
OBJECT_STORE_BYTES = 200 * 2**20  # env messages are a few hundred bytes; Ray's default is 30% of the RAM
START_TIMEOUT = 90.0             # s for a node to start (Ray's daemons and the first worker, on a busy machine)
STOP_TIMEOUT = 45.0              # s for a node to end after SIGTERM (Ray drains for up to 30 s) before SIGKILL
STARTED_LINE = "Ray runtime started"  # what `ray start` prints once its node is up
PROBE_TIMEOUT = 5.0              # s for the cluster's address to accept a TCP connection
CONNECT_TIMEOUT = 60.0           # s for ray.init to join a cluster whose address accepts connections
RAY_DIR = "r"                    # Ray's temp folder, inside ours


class ClusterError(RuntimeError):
    """A node could not start, stop or be found; the message says what to check."""


@dataclass(frozen=True)
class NodeRecord:
    """A node this machine started (node.json)."""

    pid: int          # `ray start --block`, the leader of the node's process group
    address: str      # the cluster's address HOST:PORT (the head's GCS)
    head: bool
    temp_dir: str     # Ray's temp folder of this node


def state_dir(path: Path | str | None = None) -> Path:
    """The state folder: `path`, else $ROBOT_RL_CLUSTER_DIR."""
    if path is not None:
        return Path(path)
    if not os.environ.get(STATE_DIR_ENV):
        raise ClusterError(f"{STATE_DIR_ENV} is not set: run this inside the workspace environment (./ws cluster ...)")
    return Path(os.environ[STATE_DIR_ENV])


def token_path(folder: Path) -> Path:
    return folder / "auth_token"


def ray_environment(token: Path, base: dict[str, str] | None = None) -> dict[str, str]:
    """The environment of a node, and of a driver: `base` (default this process's) with usage statistics off and
    token authentication with the token in `token`."""
    return {**(os.environ if base is None else base), "RAY_USAGE_STATS_ENABLED": "0", "RAY_AUTH_MODE": "token",
            "RAY_AUTH_TOKEN_PATH": str(token)}


def split_address(address: str) -> tuple[str, int]:
    """HOST and PORT (1-65535) of a cluster's address HOST:PORT; ClusterError naming it if it is not one."""
    match = re.fullmatch(r"\[?([A-Za-z0-9_.:-]+?)\]?:(\d{1,5})", address)
    if match is None or not 1 <= int(match[2]) <= 65535:
        raise ClusterError(f"'{address}' is not a cluster address HOST:PORT (a port from 1 to 65535), e.g. "
                           f"192.168.1.10:{DEFAULT_PORT}")
    return match[1], int(match[2])


def port_number(text: str) -> int:
    """A port from 1 to 65535 (argparse type; 0 is refused: the head's port is what others name)."""
    if not re.fullmatch(r"\d{1,5}", text) or not 1 <= int(text) <= 65535:
        raise argparse.ArgumentTypeError(f"'{text}' is not a port from 1 to 65535")
    return int(text)


def ray_dir(temp_dir: Path | str) -> Path:
    """Ray's temp folder inside a node's private temp folder (new_temp_dir)."""
    return Path(temp_dir) / RAY_DIR


def ray_start_command(temp_dir: Path, address: str | None = None, port: int = DEFAULT_PORT,
                      num_cpus: int | None = None, extra: Sequence[str] = ()) -> list[str]:
    """`ray start --block` for a head (address None) or a node joining `address`, with the workspace's options."""
    command = [sys.executable, "-m", "ray.scripts.scripts", "start", "--block", "--temp-dir", str(ray_dir(temp_dir)),
               "--disable-usage-stats", "--object-store-memory", str(OBJECT_STORE_BYTES)]
    command += ["--head", "--port", str(port), "--include-dashboard=false"] if address is None else \
        ["--address", address]
    if num_cpus is not None:
        command += ["--num-cpus", str(num_cpus)]
    return command + list(extra)


def new_temp_dir() -> Path:
    """A private folder with a short path (mkdtemp: mode 0700) for Ray's temp folder (ray_dir)."""
    return Path(tempfile.mkdtemp(prefix="rrl-ray-", dir="/tmp"))


def make_private(temp_dir: Path | str) -> None:
    """Every folder in `temp_dir` (Ray's, which it makes 0777) set to 0700; `temp_dir` itself is 0700 already."""
    for root, folders, _ in os.walk(temp_dir):
        for folder in folders:
            path = os.path.join(root, folder)
            if not os.path.islink(path):  # Ray's session_latest: a link to a folder that is here too
                with contextlib.suppress(OSError):  # gone meanwhile
                    os.chmod(path, 0o700)


def ensure_token(path: Path) -> None:
    """A random token in `path` (mode 0600) unless one is there."""
    if path.is_file():
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    descriptor = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(descriptor, "w") as file:
        file.write(secrets.token_hex(32))


def wait_started(process: subprocess.Popen[bytes], log: Path, timeout: float = START_TIMEOUT) -> None:
    """Wait (bounded) until `ray start` says its node is up; ClusterError with the log's end if it exits or is late."""
    deadline = time.monotonic() + timeout
    while STARTED_LINE not in log.read_text(errors="replace"):
        if process.poll() is not None:
            raise ClusterError(f"ray start exited with code {process.returncode}; its log ({log}):\n{_tail(log)}")
        if time.monotonic() > deadline:
            raise ClusterError(f"the Ray node was not up within {timeout:.0f} s (is the machine overloaded, or the "
                               f"head unreachable?); its log ({log}):\n{_tail(log)}")
        time.sleep(0.1)


def head_address(temp_dir: Path) -> str:
    """The address a head wrote into its temp folder (HOST:PORT)."""
    return (ray_dir(temp_dir) / "ray_current_cluster").read_text().strip()


def _tail(path: Path, lines: int = 15) -> str:
    try:
        return "\n".join(path.read_text(errors="replace").splitlines()[-lines:])
    except OSError:
        return "(no log)"


def _record_path(folder: Path) -> Path:
    return folder / "node.json"


def _recorded(folder: Path) -> NodeRecord | None:
    try:
        return NodeRecord(**json.loads(_record_path(folder).read_text()))
    except (OSError, ValueError, TypeError):
        return None


def read_record(folder: Path) -> NodeRecord | None:
    """The node this state folder started, if it still runs (nothing is changed: clean_up removes a dead one's)."""
    record = _recorded(folder)
    return record if record is not None and _is_node(record) else None


def _is_node(record: NodeRecord) -> bool:
    """Whether record.pid is still that node's `ray start` (not a pid reused since, nor its zombie)."""
    try:
        command = Path(f"/proc/{record.pid}/cmdline").read_bytes().split(b"\0")
    except OSError:
        return False
    return b"start" in command and str(ray_dir(record.temp_dir)).encode() in command


@contextlib.contextmanager
def locked(folder: Path) -> Iterator[None]:
    """Hold the state folder's cluster.lock (flock, released when this process ends, however it ends); a
    ClusterError at once if another ./ws cluster command holds it."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "cluster.lock"
    with lock_while(path, 0o600) as held:  # not inherited by ray start
        if not held:
            raise ClusterError(f"another ./ws cluster start, join or stop of this workspace is under way (it holds "
                               f"{path}): wait for it, then ./ws cluster status")
        yield


def clean_up(folder: Path) -> NodeRecord | None:
    """(Holding the lock.) The dead node a record names: what is left of its process group killed, its temp folder
    removed, the record dropped; returns that record (None: no record, or its node runs)."""
    record = _recorded(folder)
    if record is None or _is_node(record):
        return None
    _reap(record.pid)
    if not _alive(record.pid):  # the leader is gone: its group's pgid cannot have been reused while members live
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(record.pid, signal.SIGKILL)
    shutil.rmtree(record.temp_dir, ignore_errors=True)
    _record_path(folder).unlink(missing_ok=True)
    return record


def start_node(folder: Path, address: str | None = None, port: int = DEFAULT_PORT, num_cpus: int | None = None,
               extra: Sequence[str] = ()) -> NodeRecord:
    """Start this machine's node: a head (address None) or one joining `address`; ClusterError if one runs."""
    if address is not None:
        split_address(address)
    with locked(folder):
        clean_up(folder)
        return _start_node(folder, address, port, num_cpus, extra)


def _start_node(folder: Path, address: str | None, port: int, num_cpus: int | None,
                extra: Sequence[str]) -> NodeRecord:
    running = read_record(folder)
    if running is not None:
        raise ClusterError(f"a Ray node of this workspace runs already (pid {running.pid}, cluster "
                           f"{running.address}): ./ws cluster stop ends it")
    token = token_path(folder)
    if address is None:
        ensure_token(token)
    elif not token.is_file():
        raise ClusterError(f"joining {address} needs the head's token: copy the head machine's .ws/cluster/auth_token "
                           f"to {token} (mode 0600)")
    folder.mkdir(parents=True, exist_ok=True)
    temp_dir = new_temp_dir()
    log = folder / "node.log"
    with open(log, "wb") as output:
        process = subprocess.Popen(ray_start_command(temp_dir, address, port, num_cpus, extra),
                                   env=ray_environment(token), stdin=subprocess.DEVNULL, stdout=output,
                                   stderr=subprocess.STDOUT, start_new_session=True)
    try:
        wait_started(process, log)
        make_private(temp_dir)
        record = NodeRecord(process.pid, head_address(temp_dir) if address is None else address, address is None,
                            str(temp_dir))
    except BaseException:
        end_node(process.pid, temp_dir)
        raise
    _record_path(folder).write_text(json.dumps(asdict(record)))
    return record


def end_node(pid: int, temp_dir: Path | str, timeout: float = STOP_TIMEOUT) -> None:
    """End a node started with start_new_session by its pid: SIGTERM (Ray drains and ends its processes), then
    SIGKILL to its process group; bounded. Its temp folder is removed."""
    try:
        os.kill(pid, signal.SIGTERM)
        deadline = time.monotonic() + timeout
        while _alive(pid) and time.monotonic() < deadline:
            time.sleep(0.1)
        os.killpg(pid, signal.SIGKILL)  # what is left of the group (nothing, after a clean end)
    except ProcessLookupError:
        pass
    _reap(pid)
    shutil.rmtree(temp_dir, ignore_errors=True)


def _alive(pid: int) -> bool:
    """Whether `pid` runs (a zombie child of ours counts as ended, and is reaped)."""
    _reap(pid)
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _reap(pid: int) -> None:
    try:
        os.waitpid(pid, os.WNOHANG)
    except ChildProcessError:  # not our child: init reaps it
        pass


def stop_node(folder: Path) -> NodeRecord | None:
    """End this workspace's node (None: none ran); a dead one's remains are cleaned up."""
    with locked(folder):
        clean_up(folder)
        record = read_record(folder)
        if record is None:
            return None
        end_node(record.pid, record.temp_dir)
        _record_path(folder).unlink(missing_ok=True)
        return record


def status(folder: Path) -> str:
    """This workspace's node and, when one runs, `ray status` of its cluster; a dead node's remains cleaned up."""
    with locked(folder):
        dead = clean_up(folder)
        record = read_record(folder)
    if record is None:
        gone = f"the node of {dead.address} (pid {dead.pid}) had died: its temp folder {dead.temp_dir} is removed; " \
            if dead is not None else ""
        return f"{gone}no Ray node of this workspace runs (./ws cluster start, or ./ws cluster join ADDRESS)"
    role = "head" if record.head else "node joined to"
    lines = [f"{role} {record.address}: pid {record.pid}, Ray temp folder {record.temp_dir}"]
    result = subprocess.run([sys.executable, "-m", "ray.scripts.scripts", "status", "--address", record.address],
                            env=ray_environment(token_path(folder)), capture_output=True, text=True, timeout=60)
    lines.append(result.stdout.strip() or result.stderr.strip())
    return "\n".join(lines)


def driver_address(cluster: str, folder: Path | None = None) -> str:
    """The address a driver connects to: "ray" is this workspace's node's cluster, else `cluster` as given."""
    if cluster != "ray":
        if ":" not in cluster:
            raise ClusterError(f"cluster '{cluster}' is neither 'ray' nor an address HOST:PORT")
        split_address(cluster)
        return cluster
    record = read_record(state_dir(folder))
    if record is None:
        raise ClusterError("cluster:=ray needs this workspace's Ray node: ./ws cluster start (or join ADDRESS) first")
    return record.address


def prepare_driver(folder: Path | None = None) -> None:
    """Set this process's environment as a driver's: usage statistics off, and this workspace's token when there
    is one (else the RAY_AUTH_* variables as they are). Before ray is imported: Ray reads them then."""
    os.environ["RAY_USAGE_STATS_ENABLED"] = "0"
    if folder is not None or os.environ.get(STATE_DIR_ENV):
        token = token_path(state_dir(folder))
        if token.is_file():
            os.environ.update(ray_environment(token, {}))


def connect(cluster: str, folder: Path | None = None, **init_kwargs: Any) -> str:
    """ray.init() on `cluster` (see driver_address) as prepare_driver() prepares it; returns the address. The
    workers' output stays in their node's logs (log_to_driver=False) unless init_kwargs say otherwise."""
    address = driver_address(cluster, folder)
    prepare_driver(folder)
    bounded_init(address, **{"log_to_driver": False, "logging_level": "WARNING", **init_kwargs})
    return address


def probe(address: str, timeout: float = PROBE_TIMEOUT) -> None:
    """ClusterError naming `address` unless its port accepts a TCP connection within `timeout` (Ray's GCS)."""
    host, port = split_address(address)
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except OSError as error:
        reason = f"no answer within {timeout:.0f} s" if isinstance(error, TimeoutError) else error.strerror or error
        raise ClusterError(f"no Ray cluster at {address}: nothing accepts connections there ({reason}): is its head "
                           f"up, and the address its GCS port? (./ws cluster status on the head)") from None


def bounded_init(address: str, timeout: float = CONNECT_TIMEOUT, **init_kwargs: Any) -> None:
    """probe(address), then ray.init(address=...) in a thread, waited for at most `timeout`; SIGTERM or SIGINT
    from the probe on ends it at once (the signal is then handled as it would have been, and a ClusterError raised).
    ClusterError naming the address if nothing listens there, or ray.init fails or is late."""
    outcome: list[BaseException | None] = []

    def init() -> None:
        try:
            ray.init(address=address, **init_kwargs)
            outcome.append(None)
        except BaseException as error:  # noqa: BLE001 (handed to the waiting thread)
            outcome.append(error)
    received: list[int] = []
    main = threading.current_thread() is threading.main_thread()
    previous: dict[int, Any] = {signum: signal.getsignal(signum) for signum in (signal.SIGTERM, signal.SIGINT)} \
        if main else {}
    previous = {signum: handler for signum, handler in previous.items() if handler is not signal.SIG_IGN}
    for signum in previous:
        signal.signal(signum, lambda number, _frame: received.append(number))
    thread = threading.Thread(target=init, name="ray.init", daemon=True)
    quiet = _NotMainThreadFilter()
    logging.getLogger("ray._private.worker").addFilter(quiet)  # Ray's warning that it sets no SIGTERM handler
    try:
        probe(address)  # a signal meanwhile is seen below (the connect goes on, PROBE_TIMEOUT at most)
        if not received:
            import ray
            deadline = time.monotonic() + timeout
            thread.start()
            while thread.is_alive() and not received and time.monotonic() < deadline:
                thread.join(0.1)
    finally:
        logging.getLogger("ray._private.worker").removeFilter(quiet)
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    if received:
        handler = previous[received[0]]
        if callable(handler):
            handler(received[0], None)  # e.g. the training node's stop request; KeyboardInterrupt for SIGINT
        elif handler == signal.SIG_DFL:
            signal.raise_signal(received[0])  # the process ends as it would have
        raise ClusterError(f"stopped ({signal.Signals(received[0]).name}) while joining the Ray cluster at {address}")
    if thread.is_alive():
        raise ClusterError(f"the Ray cluster at {address} did not let this driver join within {timeout:.0f} s: is the "
                           f"address its head's GCS port, and this machine's auth_token the head's?")
    if outcome[0] is not None:
        raise ClusterError(f"cannot join the Ray cluster at {address}: {type(outcome[0]).__name__}: "
                           f"{' '.join(str(outcome[0]).split())[:300]}")
    if previous.get(signal.SIGTERM) == signal.SIG_DFL:  # what ray.init does on the main thread: SIGTERM exits
        signal.signal(signal.SIGTERM, lambda number, _frame: sys.exit(number))


class _NotMainThreadFilter(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        return "not the main thread" not in record.getMessage()


def _cpus(text: str) -> int:
    if not re.fullmatch(r"\d{1,4}", text) or int(text) < 1:
        raise argparse.ArgumentTypeError(f"'{text}' is not a number of CPUs (1 or more)")
    return int(text)


class _OneLineParser(argparse.ArgumentParser):
    """argparse whose errors are one `[ws] error:` line (no usage above it), exit code 1 as ./ws's."""

    def error(self, message: str) -> Any:  # argparse's signature is NoReturn
        self.exit(1, f"[ws] error: {message} (./ws cluster --help)\n")


def main(argv: Sequence[str] | None = None) -> int:
    parser = _OneLineParser(prog="./ws cluster", description="this machine's Ray node for the workspace")
    commands = parser.add_subparsers(dest="command", required=True)
    start = commands.add_parser("start", help="start a Ray head on this machine")
    start.add_argument("--port", type=port_number, default=DEFAULT_PORT, help="the head's port (default %(default)s)")
    join = commands.add_parser("join", help="join the cluster whose head is at ADDRESS (HOST:PORT)")
    join.add_argument("address")
    for command in (start, join):
        command.add_argument("--num-cpus", type=_cpus, help="CPUs Ray may schedule on this node (default: all)")
        command.add_argument("--node-ip-address", help="this machine's address the others reach it at (default: "
                                                       "the address of its default route)")
    commands.add_parser("stop", help="end this workspace's Ray node")
    commands.add_parser("status", help="this workspace's Ray node and its cluster")
    args = parser.parse_args(argv)
    folder = state_dir()
    try:
        if args.command in ("start", "join"):
            extra = ["--node-ip-address", args.node_ip_address] if args.node_ip_address else []
            record = start_node(folder, args.address if args.command == "join" else None,
                                getattr(args, "port", DEFAULT_PORT), args.num_cpus, extra)
            what = "head" if record.head else "node joined to"
            print(f"Ray {what} {record.address} (pid {record.pid}); other machines join it with "
                  f"./ws cluster join {record.address} after copying {token_path(folder)}; runs use it with "
                  f"cluster:=ray")
        elif args.command == "stop":
            stopped = stop_node(folder)
            print(f"stopped the Ray node of {stopped.address} (pid {stopped.pid})" if stopped else
                  "no Ray node of this workspace runs")
        else:
            print(status(folder))
    except ClusterError as error:
        print(f"[ws] error: {error}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
