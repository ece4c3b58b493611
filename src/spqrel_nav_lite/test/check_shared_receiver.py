#!/usr/bin/python3
"""rostest: SharedReceiver delivers what rospy's own receiving threads deliver.

One node publishes and subscribes to itself (rospy connects to its own publishers over TCP,
as to any other), with three topics managed by the receiver and one that is not."""
import threading
import time
import unittest
import warnings

import rospy
import rospy.impl.tcpros
import rostest
from std_msgs.msg import Int32

from spqrel_nav_lite.shared_receiver import SharedReceiver


def wait_until(cond, timeout=20.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.02)
    return cond()


def thread_names():
    return {t.name for t in threading.enumerate() if t.is_alive()}


class SharedReceiverTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        # with nav_host's default wait for a burst's other messages (coalesce)
        cls.receiver = SharedReceiver(["/sr/a", "/sr/latched", "/sr/burst", "/sr/last"],
                                      coalesce=0.001).install()

    def collect(self, topic, queue_size=None):
        got = []
        sub = rospy.Subscriber(topic, Int32, lambda m: got.append(m), queue_size=queue_size)
        return sub, got

    def test_order_and_threads(self):
        """Every message, in order, with its connection header; no thread of rospy's for the
        managed topic, one for the other."""
        pub_a = rospy.Publisher("/sr/a", Int32, queue_size=100)
        pub_b = rospy.Publisher("/sr/b", Int32, queue_size=100)
        sub_a, got_a = self.collect("/sr/a")
        sub_b, got_b = self.collect("/sr/b")
        self.assertTrue(wait_until(lambda: pub_a.get_num_connections() == 1
                                   and pub_b.get_num_connections() == 1))
        self.assertTrue(wait_until(lambda: sub_a.get_num_connections() == 1))
        before = self.receiver.messages
        for i in range(200):
            pub_a.publish(Int32(i))
            pub_b.publish(Int32(i))
            time.sleep(0.002)
        self.assertTrue(wait_until(lambda: len(got_a) == 200 and len(got_b) == 200),
                        f"received {len(got_a)} and {len(got_b)} of 200")
        self.assertEqual([m.data for m in got_a], list(range(200)))
        self.assertEqual(self.receiver.messages - before, 200)
        self.assertEqual(got_a[0]._connection_header["topic"], "/sr/a")
        self.assertEqual(got_a[0]._connection_header["type"], "std_msgs/Int32")
        names = thread_names()
        self.assertNotIn("/sr/a", names)          # rospy names its receiving thread by topic
        self.assertIn("/sr/b", names)
        self.assertFalse(any(n.endswith("(connect)") for n in names), names)
        # the publisher goes away: the connection is closed and dropped, as rospy does
        pub_a.unregister()
        self.assertTrue(wait_until(lambda: sub_a.get_num_connections() == 0),
                        "the connection of an unregistered publisher stayed")
        self.assertTrue(wait_until(lambda: not self.receiver._conns or all(
            c.name != "/sr/a" for c in self.receiver._conns)))
        sub_a.unregister()
        sub_b.unregister()
        pub_b.unregister()

    def test_latched(self):
        pub = rospy.Publisher("/sr/latched", Int32, queue_size=1, latch=True)
        pub.publish(Int32(7))
        sub, got = self.collect("/sr/latched")
        self.assertTrue(wait_until(lambda: len(got) == 1), "the latched message did not come")
        self.assertEqual(got[0].data, 7)
        sub.unregister()
        pub.unregister()

    def held_at_first_message(self, topic, queue_size=None):
        """A publisher without a send queue (what publish() wrote is in the socket when it
        returns) and a subscriber whose callback holds the receiving thread at message 0 until
        ``hold`` is set; message 0 is published and has arrived. (pub, sub, got, hold)"""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            pub = rospy.Publisher(topic, Int32, queue_size=None)
        hold = threading.Event()
        got = []

        def slow(m):
            got.append(m.data)
            if m.data == 0:
                hold.wait(10)
        sub = rospy.Subscriber(topic, Int32, slow, queue_size=queue_size)
        self.assertTrue(wait_until(lambda: pub.get_num_connections() == 1
                                   and sub.get_num_connections() == 1))
        pub.publish(Int32(0))
        self.assertTrue(wait_until(lambda: got == [0]))
        return pub, sub, got, hold

    def test_queue_size(self):
        """Of the messages read at once, only the newest queue_size are delivered (rospy's
        rule): a callback that holds the thread up sees the backlog trimmed."""
        pub, sub, got, hold = self.held_at_first_message("/sr/burst", queue_size=2)
        for i in range(1, 51):
            pub.publish(Int32(i))
        # all 50 are in the socket while the callback waits
        hold.set()
        self.assertTrue(wait_until(lambda: got and got[-1] == 50), got)
        self.assertLess(len(got), 10, f"queue_size 2 delivered {len(got)} messages: {got}")
        self.assertEqual(got[-2:], [49, 50])
        sub.unregister()
        pub.unregister()

    def test_last_messages_before_a_hang_up(self):
        """Messages that came just before the publisher hung up are delivered (read together
        with the end of the connection while the thread was held up)."""
        pub, sub, got, hold = self.held_at_first_message("/sr/last")
        for i in range(1, 6):
            pub.publish(Int32(i))
        pub.unregister()
        time.sleep(0.2)
        hold.set()
        self.assertTrue(wait_until(lambda: sub.get_num_connections() == 0))
        self.assertEqual(got, [0, 1, 2, 3, 4, 5])
        sub.unregister()

    def test_z_manage_later_then_close(self):
        """A topic added with manage() is taken over; close() gives rospy its seam back,
        ends the thread and closes the connections it read. (Runs last: z.)"""
        self.receiver.manage("/sr/later")
        pub = rospy.Publisher("/sr/later", Int32, queue_size=10)
        sub, got = self.collect("/sr/later")
        self.assertTrue(wait_until(lambda: pub.get_num_connections() == 1
                                   and sub.get_num_connections() == 1))
        self.assertTrue(wait_until(lambda: any(c.name == "/sr/later"
                                               for c in list(self.receiver._conns))))
        pub.publish(Int32(3))
        self.assertTrue(wait_until(lambda: [m.data for m in got] == [3]))
        self.assertNotIn("/sr/later", thread_names())
        handler = rospy.impl.tcpros.get_tcpros_handler()
        self.assertEqual(handler.create_transport, self.receiver._create_transport)
        self.receiver.close()
        self.assertNotEqual(handler.create_transport, self.receiver._create_transport)
        self.assertFalse(self.receiver._thread.is_alive())
        self.assertTrue(wait_until(lambda: sub.get_num_connections() == 0),
                        "close() left the connection it read open")
        sub.unregister()
        pub.unregister()


if __name__ == "__main__":
    rospy.init_node("shared_receiver_check")
    rostest.rosrun("spqrel_nav_lite", "shared_receiver_check", SharedReceiverTest)
