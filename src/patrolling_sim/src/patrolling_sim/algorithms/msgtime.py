"""Times of day in /results payloads, for algorithms that share when something happens
(ER's expected arrivals, RWF's flag writes).

Every payload entry is an int16 (``docs/protocol.md``), too small for simulated seconds in
tenths over a long run. A time ``t`` (s) is therefore sent as its count of tenths of a
second modulo 32768 (``0..32767``), and the receiver restores it as the time nearest its own
clock that has that code. All robots share one clock (simulated time in graph mode, ROS time
in ROS mode), so the round trip is exact, whatever the message delay, for every time within
:data:`HORIZON` seconds of the receiver's clock; a sender keeps what it sends within that
window (an expected arrival at a neighbour, a visit one edge ago).

    code = encode_time(1234.56)          # 12346
    decode_time(code, now=1300.0)        # 1234.6
"""

#: resolution of a sent time (s)
TICK = 0.1
#: codes are taken modulo this (2**15: every code fits a non-negative int16)
WRAP = 32768
#: a time decodes exactly while it is less than this far from the receiver's clock (s)
HORIZON = (WRAP // 2) * TICK


def encode_time(t: float) -> int:
    """The payload code of time ``t`` (s): its tenths of a second, rounded, modulo 32768."""
    return int(round(t / TICK)) % WRAP


def decode_time(code: int, now: float) -> float:
    """The time (s, to the tenth) nearest ``now`` whose code is ``code``."""
    base = int(round(now / TICK))
    k = (int(code) - base) % WRAP
    if k >= WRAP // 2:
        k -= WRAP
    return round((base + k) * TICK, 1)
