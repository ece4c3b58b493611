"""One thread receives the messages of many topic subscriptions (docs/navigation.md, "Threads").

rospy reads every subscribed connection in a thread of its own: a process hosting the
navigation of many robots runs three receiving threads per robot (odometry, ground truth and
laser scans), each woken by the kernel for every message and each contending for the GIL; one
thread for all of them avoids that (bench/notes/runner.md, "One receiving thread").

:class:`SharedReceiver` takes over the subscriber connections of the topics it is given: rospy
still negotiates them (``requestTopic``) and still does the TCPROS handshake (in a short-lived
thread, with rospy's retries), but once connected the socket is handed to one thread that waits
on all of them with ``epoll``, reads whatever has arrived, deserializes complete messages with
rospy's own code and calls the subscriber's callbacks, in the order the messages arrived on
each connection. What subscribers see is unchanged: the same message objects (with
``_connection_header``), the same ``queue_size`` rule (of the messages read at once, only the
newest ``queue_size`` are delivered), the same statistics for ``getBusStats``, the same
clean-up when the publisher goes away. Topics it is not given keep rospy's thread.

It works through one documented seam of rospy: the TCPROS protocol handler
(``rospy.impl.tcpros.get_tcpros_handler()``), whose ``create_transport`` it wraps.

Differences from rospy's receiving thread, both deliberate:

- a connection whose message does not decode is closed, as one that hangs up or fails at the
  socket is (by rospy too); rospy's thread instead reconnects to the same address after such an
  error, to a publisher that would send the same bytes again;
- the callbacks of all taken-over connections run one after the other in one thread, so a slow
  callback delays the others (the navigation's callbacks store the message and return; the
  localiser's scan update is the slowest, docs/navigation.md).
"""
import logging
import selectors
import socket
import threading
import time

import rospy
import rospy.impl.registration
import rospy.impl.tcpros
from rospy.impl.tcpros_base import TCPROS, TCPROSTransport, recv_buff
from rospy.impl.tcpros_pubsub import TCPROSSub, check_if_still_publisher
from rospy.exceptions import TransportInitError, TransportTerminated

_log = logging.getLogger("rospy.spqrel_nav_lite.shared_receiver")


class SharedReceiver:
    """Receive the connections of the managed topics in one thread.

    ``topics``: resolved topic names to manage (more with :meth:`manage`). Call
    :meth:`install` before the subscribers are created (their connections are made
    afterwards, in rospy's registration threads; before ``rospy.init_node`` to include
    ``/clock``). The thread ends at rospy's shutdown, or at :meth:`close`.

    ``coalesce`` (wall s, default 0): after the first message of a burst the thread waits
    this long, then reads every connection that has data. The simulator's messages of one
    step (every robot's odometry, ground truth and scan) arrive one by one; without the wait
    the thread wakes for each, with it about once per step, and so do the callbacks' readers
    (the control loop). The messages are delayed by at most that long."""

    #: how long the thread waits in one ``select``: how soon it notices shutdown
    SELECT_TIMEOUT = 0.5

    def __init__(self, topics=(), name="shared_receiver", coalesce=0.0):
        self._topics = set(topics)
        self.coalesce = float(coalesce)
        self._handler = rospy.impl.tcpros.get_tcpros_handler()
        self._original = None
        self._selector = selectors.DefaultSelector()
        self._lock = threading.Lock()
        self._incoming = []              # (conn, callback) connected, not yet selected
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._selector.register(self._wake_r, selectors.EVENT_READ, None)
        self._conns = {}                 # conn -> callback
        self._stop = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self.messages = 0                #: messages delivered
        self.wakeups = 0                 #: passes that found messages
        self._handed = 0

    def manage(self, resolved_name):
        """Take over the connections of ``resolved_name`` made from now on."""
        with self._lock:
            self._topics.add(resolved_name)

    @property
    def connections(self):
        """Connections handed to the thread so far (open or closed since)."""
        return self._handed

    def manages(self, resolved_name):
        with self._lock:
            return resolved_name in self._topics

    # -- rospy's seam ------------------------------------------------------------------------
    def install(self):
        """Route the new subscriber connections of the managed topics here; start the thread."""
        if self._original is not None:
            return self
        self._original = self._handler.create_transport
        self._handler.create_transport = self._create_transport
        self._thread.start()
        return self

    def close(self):
        """Give ``create_transport`` back to rospy, stop the thread and close the connections
        it was reading (their subscribers get no more messages from them)."""
        if self._original is not None:
            if self._handler.create_transport == self._create_transport:
                self._handler.create_transport = self._original
            self._original = None
        self._stop = True
        self._wake()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout=2.0)

    def _create_transport(self, resolved_name, pub_uri, protocol_params):
        """rospy's ``TCPROSHandler.create_transport``, except that the connected socket is
        read by this receiver's thread instead of a thread of its own."""
        if not self.manages(resolved_name) or self._stop:
            return self._original(resolved_name, pub_uri, protocol_params)
        if type(protocol_params) != list or len(protocol_params) != 3:
            return 0, "ERROR: invalid TCPROS parameters", 0
        if protocol_params[0] != TCPROS:
            return 0, "INTERNAL ERROR: protocol id is not TCPROS: %s" % protocol_params[0], 0
        _, dest_addr, dest_port = protocol_params
        sub = rospy.impl.registration.get_topic_manager().get_subscriber_impl(resolved_name)
        if sub is None:
            return 0, "ERROR: no subscriber for topic [%s]" % resolved_name, 0
        protocol = TCPROSSub(resolved_name, sub.data_class, queue_size=sub.queue_size,
                             buff_size=sub.buff_size, tcp_nodelay=sub.tcp_nodelay)
        conn = TCPROSTransport(protocol, resolved_name)
        conn.set_endpoint_id(pub_uri)
        t = threading.Thread(name=resolved_name + " (connect)", target=self._connect,
                             args=(conn, dest_addr, dest_port, pub_uri, sub.receive_callback,
                                   resolved_name), daemon=True)
        if sub.add_connection(conn):
            t.start()
            return 1, "Connected topic[%s]. Transport impl[%s] (shared receiver)" % (
                resolved_name, conn.__class__.__name__), dest_port
        conn.close()
        return 0, "ERROR: Race condition failure creating topic subscriber [%s]" % resolved_name, 0

    def _connect(self, conn, dest_addr, dest_port, pub_uri, callback, resolved_name):
        """rospy's ``robust_connect_subscriber`` up to the handshake, then hand over."""
        interval = 0.5
        while conn.socket is None and not conn.done and not rospy.is_shutdown():
            try:
                conn.connect(dest_addr, dest_port, pub_uri, timeout=60.)
            except TransportInitError as e:
                if conn.protocol is None:
                    conn.done = True
                    break
                rospy.core.rospyerr("unable to create subscriber transport: %s.  Will try "
                                    "again in %ss", e, interval)
                if interval < 30.0:
                    interval *= 2
                time.sleep(interval)
                conn.done = not check_if_still_publisher(resolved_name, pub_uri)
        if conn.done or conn.socket is None or rospy.is_shutdown():
            return
        conn.socket.setblocking(False)
        with self._lock:
            self._incoming.append((conn, callback))
            self._handed += 1
        self._wake()

    def _wake(self):
        try:
            self._wake_w.send(b"x")
        except OSError:
            pass

    # -- the receiving thread ----------------------------------------------------------------
    def _run(self):
        try:
            while not self._stop and not rospy.is_shutdown():
                # connections closed elsewhere (rospy's unsubscribe) go first, so that a
                # new socket given the same descriptor number can be registered
                self._drop_closed()
                self._take_incoming()
                events = self._selector.select(self.SELECT_TIMEOUT)
                if any(key.data is not None for key, _ in events):
                    self.wakeups += 1
                    if self.coalesce > 0:
                        # a burst (the simulator's step: every robot's odometry, ground
                        # truth and scan) is read in one pass, not one wake-up per message
                        time.sleep(self.coalesce)
                        events = self._selector.select(0)
                for key, _ in events:
                    conn = key.data
                    if conn is None:
                        self._drain_wake()
                    else:
                        self._read(conn)
        finally:
            for conn in list(self._conns):
                self._forget(conn)
                conn.close()

    def _take_incoming(self):
        with self._lock:
            incoming, self._incoming = self._incoming, []
        for conn, callback in incoming:
            if conn.done or conn.socket is None:
                continue
            try:
                self._register(conn)
            except (KeyError, ValueError, OSError):    # closed meanwhile
                continue
            self._conns[conn] = callback
            # data that came with the handshake, or before the registration
            self._read(conn)

    def _register(self, conn):
        try:
            self._selector.register(conn.socket, selectors.EVENT_READ, conn)
        except KeyError:
            # the descriptor number of a connection closed since the last pass, reused
            old = self._selector.get_key(conn.socket.fileno()).data
            if old is None or not (old.done or old.socket is None):
                raise
            self._forget(old)
            self._selector.register(conn.socket, selectors.EVENT_READ, conn)

    def _drain_wake(self):
        try:
            while self._wake_r.recv(4096):
                pass
        except (BlockingIOError, InterruptedError):
            pass

    def _drop_closed(self):
        for conn in [c for c in self._conns if c.done or c.socket is None]:
            self._forget(conn)

    def _forget(self, conn):
        self._conns.pop(conn, None)
        for fileobj in list(self._selector.get_map().values()):
            if fileobj.data is conn:
                try:
                    self._selector.unregister(fileobj.fileobj)
                except (KeyError, ValueError, OSError):
                    pass

    def _read(self, conn):
        """Read what has arrived on ``conn``; deliver its complete messages."""
        sock, b = conn.socket, conn.read_buff
        if sock is None or conn.done:
            self._forget(conn)
            return
        ended = None
        msgs = []
        try:
            try:
                while True:
                    n = recv_buff(sock, b, conn.protocol.buff_size)
                    if n == 0:
                        break
                    conn.stat_bytes += n
            except TransportTerminated as e:   # hung up, or a socket error, as in rospy
                ended = e
            # the complete messages read before a hang-up are delivered, as rospy does
            if b.tell() >= 4:
                conn.protocol.read_messages(b, msgs, sock)
        except Exception as e:                 # undecodable message
            rospy.core.logwarn("%s: closing the connection of [%s] to %s: %s",
                               rospy.get_name(), conn.name, conn.endpoint_id, e)
            self._forget(conn)
            conn.close()
            return
        if ended is not None:
            rospy.core.logdebug("[%s] failed to receive incoming message : %s", conn.name, ended)
        if msgs and not conn.done:
            self._deliver(conn, msgs)
        if ended is not None:
            self._forget(conn)
            conn.close()

    def _deliver(self, conn, msgs):
        conn.stat_num_msg += len(msgs)
        for m in msgs:
            m._connection_header = conn.header
        if conn.is_latched:
            conn.latch = msgs[-1]
        self.messages += len(msgs)
        try:
            self._conns[conn](msgs, conn)      # rospy logs (and survives) callback errors
        except Exception:
            _log.exception("receive callback of [%s]", conn.name)
