"""The numbers of the /results protocol, named once (docs/protocol.md).

Every /results message is an ``Int16MultiArray`` ``[sender id, message type, payload...]``;
the monitor's sender id is -1. These are the original's numbers: changing any of them
breaks compatibility with the original's agents and monitor. Pure constants, no imports.
"""

#: sender id of the monitor
MONITOR_ID = -1

#: ``[id, 10, 1]`` a robot is ready; ``[-1, 10, 100]`` GO; ``[-1, 10, 999]`` END
MSG_INIT = 10
#: ``[id, 11, vertex]`` a robot reached (visited) a vertex
MSG_TARGET_REACHED = 11
#: ``[id, 12]`` a robot detected an interference
MSG_INTERFERENCE = 12
#: ``[id, 13, 0|1]`` a robot failed (0) or was repaired (1) (fault scenarios)
MSG_ROBOT_STATUS = 13
#: first message type of the algorithms' own messages (the life cycle hands types >= this
#: to the strategy)
FIRST_ALGORITHM_TYPE = 30
#: ``[id, 31, vertex]`` GBS: reached a vertex
MSG_GBS_REACHED = 31
#: ``[id, 32, vertex, next]`` SEBS and CBLS: reached a vertex, heading to the next
MSG_SEBS_REACHED = 32
#: ``[id, 40, idleness x n..., next]`` DTAG/DTAP: the shared idleness table
MSG_DTA_IDLENESS = 40
#: ``[id, 41, vertex, bid]`` DTAP: a robot auctions a vertex with its own bid
MSG_SSI_TASK_REQUEST = 41
#: ``[id, 42, vertex, bid]`` DTAP: an answer to an auction with a better bid
MSG_SSI_BID = 42
#: ``[id, 50, vertex, next, eta]`` ER: reached a vertex, heading to ``next``, expected there
#: at ``eta`` (algorithms.msgtime: tenths of a second modulo 32768)
MSG_ER_VISIT = 50
#: ``[id, 51, next, eta]`` ER: a new goal without a visit (after a failed goal or a repair)
MSG_ER_INTENTION = 51
#: ``[id, 52, vertex, t, prev, t_prev]`` RWF: flag writes at ``vertex``: visited at ``t``,
#: by a robot coming from ``prev`` (-1: none) that visited it at ``t_prev`` (msgtime codes)
MSG_RWF_VISIT = 52
#: ``[id, 53, vertex, next, t]`` RWF: flag write at ``vertex``: a robot left for ``next`` at
#: ``t`` (msgtime code)
MSG_RWF_DEPART = 53
#: ``[id, 54, vertex, ask]`` IC: a robot reached a vertex; ``ask`` 1: it asks the coordinator
#: for a goal, 0: a visit on its way (or the coordinator's own)
MSG_IC_REQUEST = 54
#: ``[id, 55, robot, goal]`` IC: ``robot`` is to head to ``goal`` (from the coordinator, or
#: from the robot itself when it gave up waiting)
MSG_IC_ASSIGN = 55
#: ``[id, 56, vertex, seed]`` AHPA: a robot reached a vertex; its Voronoi cell grows from
#: ``seed``
MSG_AHPA_POSITION = 56
#: ``[id, 57, vertex, next]`` the learning environment's robots (patrolling_sim.envs): reached
#: a vertex, heading to ``next``; what the teammates believe comes from these
MSG_LEARNED_VISIT = 57

#: payloads of MSG_INIT from the monitor / from a robot
GO = 100
END = 999
ROBOT_READY = 1
#: s: after GO each agent waits a random U(0, START_DELAY_MAX) s before its first goal, so
#: that the robots do not all start at once (the original's agents do the same)
START_DELAY_MAX = 1.0

#: largest value of an int16 payload entry (every /results entry is an int16)
INT16_MAX = 32767
#: what the original's DTA agents send instead of an idleness entry (10 x seconds) or a bid
#: that does not fit an int16
INT16_CAP = 32000

#: the original monitor's rule for the global minimum idleness: while the recorded minimum
#: is below this (s), the next sample replaces it (docs/monitor.md)
MIN_IDLENESS_FLOOR = 0.1
