"""workspace_tools.live_runs: the port a ./ws run takes and the runs ./ws plot, rviz and exec join (a record
whose launcher is gone is removed; one whose master does not answer is skipped)."""
import os
import socket

from workspace_tools import live_runs


def test_a_taken_port_is_seen_and_a_free_one_is_not(tmp_path):
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen()
        port = server.getsockname()[1]
        assert not live_runs.port_is_free(port)
    assert live_runs.port_is_free(port)


def test_records_of_gone_launchers_are_removed_and_silent_masters_skipped(tmp_path):
    alive = live_runs.record(tmp_path, f"http://127.0.0.1:{live_runs.free_port()}", "run-id", "./ws run cube")
    assert alive.name == f"{os.getpid()}.json"
    gone = tmp_path / "4194000.json"
    gone.write_text(alive.read_text().replace(str(os.getpid()), "4194000"))
    assert live_runs.live_runs(tmp_path) == []  # this process is alive, but no master answers at that port
    assert alive.exists() and not gone.exists()
