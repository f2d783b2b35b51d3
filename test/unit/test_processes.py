"""Unit tests for workspace_tools.processes' start and stop (no master): SIGINT ends what a test started, also
when pytest itself ignores or blocks SIGINT (bash starts a background job of a non-interactive shell with
SIGINT ignored), and a process that outlives SIGINT is killed and named."""
import signal
import subprocess
import sys

import pytest

from workspace_tools.processes import Processes, stop


def test_a_process_started_while_sigint_is_ignored_and_blocked_ends_on_sigint(tmp_path):
    """Before: the child inherited SIG_IGN (and the mask), and stop() waited its 10 s for SIGKILL."""
    processes = Processes(tmp_path)
    try:
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            sleeper = processes.start(["sleep", "60"])
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)
            signal.signal(signal.SIGINT, previous)
        stop(sleeper)
        assert sleeper.returncode == -signal.SIGINT, "ended by SIGINT, not by the SIGKILL after 10 s"
    finally:
        processes.close()


def test_a_process_that_ignores_sigint_is_killed_with_a_warning_naming_it(tmp_path):
    processes = Processes(tmp_path)
    stubborn = processes.start([sys.executable, "-c", "import signal, time; signal.signal(signal.SIGINT, "
                                "signal.SIG_IGN); print('ignoring', flush=True); time.sleep(60)"],
                               stdout=subprocess.PIPE, text=True)
    try:
        assert stubborn.stdout.readline() == "ignoring\n"
        with pytest.warns(RuntimeWarning, match=r"still running 0.5 s after SIGINT \(it ignores SIGINT\): killed") \
                as warned:
            stop(stubborn, timeout=0.5)
        assert f"process group {stubborn.pid} (" in str(warned[0].message)
        assert stubborn.returncode == -signal.SIGKILL
    finally:
        processes.close()
        stubborn.stdout.close()
