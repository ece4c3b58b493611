"""spqrel_nav_lite.ros_util.init_node_signal_safe: SIGINT and SIGTERM end the node through
rospy.signal_shutdown called from a helper thread, never inside the main thread's signal
handler (where rospy's own handler deadlocked the abstract world: it closed the topics while
the interrupted main thread held a connection's lock inside Publisher.publish). No ROS master:
rospy.init_node and rospy.signal_shutdown are replaced by recorders."""
import os
import signal
import threading

import pytest
import rospy

from spqrel_nav_lite import ros_util


@pytest.fixture
def recorded(monkeypatch):
    """Calls of rospy.init_node / signal_shutdown, with the thread signal_shutdown ran in;
    the process's SIGINT/SIGTERM handlers are restored afterwards."""
    calls = {"init": [], "shutdown": [], "done": threading.Event()}
    monkeypatch.setattr(rospy, "init_node", lambda *a, **kw: calls["init"].append((a, kw)))

    def shutdown(reason):
        calls["shutdown"].append((reason, threading.current_thread()))
        calls["done"].set()
    monkeypatch.setattr(rospy, "signal_shutdown", shutdown)
    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    yield calls
    for s, h in saved.items():
        signal.signal(s, h)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_signal_shuts_down_from_a_helper_thread(recorded, sig):
    ros_util.init_node_signal_safe("some_node", anonymous=False)
    assert recorded["init"] == [(("some_node",), {"disable_signals": True,
                                                  "anonymous": False})]
    os.kill(os.getpid(), sig)        # handled in this (the main) thread, between bytecodes
    assert recorded["done"].wait(60), "signal_shutdown was not called"
    (reason, thread), = recorded["shutdown"]
    assert reason == f"signal-{int(sig)}"
    assert thread is not threading.main_thread()
