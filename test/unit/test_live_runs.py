"""workspace_tools.live_runs: the port a ./ws run takes and the runs ./ws plot, rviz and exec join (a record
whose launcher is gone is removed; one whose master does not answer is skipped; a claim on 11311 by a live
process keeps the next run off it)."""
import os
import socket

import pytest

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


def test_port_11311_is_taken_once_and_a_live_claim_keeps_others_off_it(tmp_path, monkeypatch):
    monkeypatch.setattr(live_runs, "port_is_free", lambda port, host="127.0.0.1": True)
    claim = tmp_path / "port-11311.claim"
    assert live_runs.claim_default_port(tmp_path)
    assert claim.read_text() == f"{os.getpid()}\n"
    assert live_runs.claim_default_port(tmp_path), "this process's own claim does not keep it off"
    claim.write_text("1\n")  # init: alive, not this process (a ./ws run whose master is starting)
    assert not live_runs.claim_default_port(tmp_path) and claim.read_text() == "1\n"
    claim.write_text(f"{2**22 + 12345}\n")  # a claimer that is gone
    assert live_runs.claim_default_port(tmp_path) and claim.read_text() == f"{os.getpid()}\n"
    live_runs.release_default_port(tmp_path)
    assert not claim.exists()
    claim.write_text("1\n")
    live_runs.release_default_port(tmp_path)
    assert claim.read_text() == "1\n", "another process's claim is not ours to remove"


@pytest.mark.parametrize("holder", ["", "garbage"])
def test_an_unreadable_claim_counts_for_nothing(tmp_path, monkeypatch, holder):
    monkeypatch.setattr(live_runs, "port_is_free", lambda port, host="127.0.0.1": True)
    (tmp_path / "port-11311.claim").write_text(holder)
    assert live_runs.claim_default_port(tmp_path)


def test_a_port_in_use_is_not_claimed(tmp_path, monkeypatch):
    monkeypatch.setattr(live_runs, "port_is_free", lambda port, host="127.0.0.1": False)
    assert not live_runs.claim_default_port(tmp_path)
    assert not (tmp_path / "port-11311.claim").exists()
