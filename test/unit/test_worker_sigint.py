"""Workers are born with SIGINT blocked, and the process that starts them loses no Ctrl-C meanwhile."""
import multiprocessing
import os
import signal
import threading
import time

import pytest

from robot_rl.workers.pipe import _workers_born_blocking_sigint


@pytest.fixture(autouse=True)
def python_sigint_handler():
    """Python's own SIGINT handler for the test, whatever pytest's is (started as a background job, as CI's
    ./ws test is, it ignores SIGINT, and so would a process it spawns)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def test_a_process_started_in_the_block_is_born_with_sigint_blocked():
    """What the workers rely on: spawn's fork and exec keep the signal mask, so a Ctrl-C pends in a worker until
    it ignores SIGINT (robot_rl.workers.pipe._worker). The child sends itself SIGINT: blocked, it pends and the
    child ends with 0; else Python's handler raises KeyboardInterrupt there (exit code 1). Before, starting
    multiprocessing's resource tracker in the block unblocked SIGINT."""
    context = multiprocessing.get_context("spawn")
    with _workers_born_blocking_sigint():
        child = context.Process(target=signal.raise_signal, args=(signal.SIGINT,), daemon=True)
        child.start()
    child.join(60)
    assert child.exitcode == 0, f"the child's SIGINT was not blocked: exit code {child.exitcode}"


def test_a_sigint_that_another_thread_takes_while_workers_are_born_still_interrupts():
    """Before: the block set SIG_IGN process-wide, and a SIGINT taken by another thread (rospy has several)
    was lost: the training node went on training after Ctrl-C until roslaunch killed it."""
    stop = threading.Event()
    other = threading.Thread(target=stop.wait, daemon=True)  # a thread that does not block SIGINT, as rospy's
    other.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            with _workers_born_blocking_sigint():
                os.kill(os.getpid(), signal.SIGINT)  # the kernel gives it to `other`: this thread blocks it
                deadline = time.monotonic() + 10
                while time.monotonic() < deadline:  # Python raises it in this thread at its next check
                    time.sleep(0.01)
    finally:
        stop.set()
        other.join(10)
