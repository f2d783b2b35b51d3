"""SIGINT and SIGTERM as a rospy shutdown that runs in a thread of its own, never in the signal handler.

A handler runs between two lines of the main thread, which may hold a lock the shutdown takes: rospy's
master proxy lock (every log line takes it to look up a param), the /rosout queue's, or a node's own
lock that one of its shutdown hooks takes (the sim node's, held while it steps and publishes). rospy's
own handler (init_node without disable_signals) runs the shutdown in the handler, so such a node
waited on itself until roslaunch's SIGKILL 17 s later. Here the shutdown thread waits for the lock
instead, and the main thread, back from the handler, lets go of it.
"""
from __future__ import annotations

import signal
import threading
from typing import Any

import rospy


def shutdown_on_signals() -> list[int]:
    """After rospy.init_node(..., disable_signals=True): SIGINT and SIGTERM start rospy's shutdown in a
    thread (rospy.is_shutdown() turns true; every rospy wait ends) and raise nothing in the main thread.
    Returns the list the handler appends each signal to. The thread is not a daemon: the process ends
    after rospy has unregistered from the master."""
    received: list[int] = []

    def handler(signum: int, _frame: Any) -> None:
        if not received:
            threading.Thread(target=rospy.signal_shutdown, args=(signal.Signals(signum).name,),
                             name="signal_shutdown").start()
        received.append(signum)
    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    return received


def shutting_down() -> bool:
    """True from the start of rospy's shutdown on (and ever after): its pre-shutdown hooks close every topic
    (publish() raises "publish() to a closed topic") before rospy.is_shutdown() turns true."""
    return rospy.core.is_shutdown_requested()
