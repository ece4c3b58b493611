"""The slot observation (docs/learning.md, "Slot observation"): one fixed-length row of
features per neighbour slot of the robot's vertex, whatever the map, its largest degree and
the team size, so that one policy that scores each slot with the same small network (shared
weights across slots and robots) runs on any graph with any team.

Scales: ``T`` (the environment's time scale: total edge length / (speed x robots)), ``L``
(the graph's mean edge length, m). For robot i on vertex c, the row of slot k (neighbour
w = the k-th neighbour of c in the graph file's order) holds, in :data:`SLOT_FEATURES`
order:

- ``valid``: 1 (0 for an empty slot, whose row is all zeros);
- ``idleness``: now - last visit of w as robot i believes it, / T;
- ``idleness_rel``: that idleness / the largest among the valid slots (1 when all are 0);
- ``best``: 1 if w has the largest believed idleness among the valid slots;
- ``length``: edge c-w / L; ``travel``: its travel time / T;
- ``mates_heading``, ``mates_at``: teammates i believes head to / stand on w;
- ``pressure``: sum over teammates j of exp(-d(next_j, w) / L), d the shortest path length
  from the vertex j said it heads to;
- ``nearest_mate``: min over teammates of d(next_j, w) / L, capped at :data:`FAR`
  (:data:`FAR` without known teammates);
- ``ahead_max``, ``ahead_mean``: largest and mean believed idleness / T of w's neighbours
  other than c (0 at a dead end);
- ``degree``: w's degree / 4.

Teammates whose position is unknown (-1, :class:`~patrolling_sim.learned.beliefs.TeamBeliefs`)
count nowhere.
"""
import numpy as np

SLOT_FEATURES = ("valid", "idleness", "idleness_rel", "best", "length", "travel",
                 "mates_heading", "mates_at", "pressure", "nearest_mate", "ahead_max",
                 "ahead_mean", "degree")
K = len(SLOT_FEATURES)
#: cap of ``nearest_mate`` (in mean edge lengths)
FAR = 10.0


class SlotTables:
    """Per-graph arrays of the slot observation, from a
    :class:`~patrolling_sim.learned.observe.GraphTables` ``tab`` and the robots' ``speed``
    (m/s): the features that depend on the vertex only, the two-hop neighbourhoods and the
    distances in mean edge lengths."""

    def __init__(self, tab, speed: float):
        self.tab = tab
        V, D = tab.n, tab.D
        self.L = max(tab.mean_edge, 1e-9)
        nb = tab.safe_nbr                                    # (V, D)
        self.static = np.zeros((V, D, K))
        self.static[:, :, 0] = tab.valid
        self.static[:, :, 4] = tab.nbr_len / self.L
        self.static[:, :, 5] = tab.nbr_len / (speed * tab.T)
        self.static[:, :, 12] = tab.degree[nb] / 4.0
        self.static[~tab.valid] = 0.0
        ahead = tab.nbr[nb]                                  # (V, D, D): w's neighbours
        self.ahead_valid = (tab.valid[nb] & (ahead != np.arange(V)[:, None, None])
                            & tab.valid[:, :, None])
        self.ahead_idx = np.where(self.ahead_valid, ahead, 0)
        self.ahead_count = np.maximum(self.ahead_valid.sum(axis=2), 1)
        d = np.asarray(tab.dist_m, dtype=float) / self.L
        #: exp(-distance) and min(distance, FAR) between vertices, with one more row and
        #: column (index V, i.e. -1) for an unknown teammate: 0 and FAR
        self.near = np.zeros((V + 1, V + 1))
        self.near[:V, :V] = np.exp(-np.where(np.isfinite(d), d, np.inf))
        self.far = np.full((V + 1, V + 1), FAR)
        self.far[:V, :V] = np.minimum(np.where(np.isfinite(d), d, FAR), FAR)


def slot_features(st: SlotTables, beliefs, ids, now: float):
    """(features (R, D, K) float32, mask (R, D) bool) of robots ``ids`` (R of them) at time
    ``now`` from ``beliefs`` (:class:`~patrolling_sim.learned.beliefs.TeamBeliefs`); module
    docstring."""
    tab = st.tab
    ids = np.asarray(ids, dtype=np.int64)
    rows = ids[:, None]
    cur = np.asarray(beliefs.current, dtype=np.int64)[ids]
    nbr = tab.safe_nbr[cur]                                  # (R, D)
    valid = tab.valid[cur]
    out = st.static[cur]                                     # a copy (fancy indexing)
    lv = beliefs.last_visit
    idl = (now - lv[rows, nbr]) * valid
    top = idl.max(axis=1, keepdims=True)
    out[:, :, 1] = idl / tab.T
    out[:, :, 2] = idl / np.where(top > 0, top, 1.0) + (top <= 0)
    out[:, :, 3] = (idl >= top - 1e-9) & valid
    mv = np.asarray(beliefs.mate_vertex, dtype=np.int64)[ids]      # (R, N)
    mn = np.asarray(beliefs.mate_next, dtype=np.int64)[ids]
    unknown = (mn < 0) | (np.arange(mn.shape[1])[None, :] == rows)
    mv[unknown] = -1
    mn[unknown] = -1
    nb3 = nbr[:, :, None]
    out[:, :, 6] = (mn[:, None, :] == nb3).sum(axis=2)
    out[:, :, 7] = (mv[:, None, :] == nb3).sum(axis=2)
    mn[unknown] = tab.n                                      # the "unknown" row of near/far
    out[:, :, 8] = st.near[nb3, mn[:, None, :]].sum(axis=2)
    out[:, :, 9] = st.far[nb3, mn[:, None, :]].min(axis=2, initial=FAR)
    ahead = st.ahead_valid[cur] * (now - lv[rows[:, :, None], st.ahead_idx[cur]])
    out[:, :, 10] = ahead.max(axis=2) / tab.T
    out[:, :, 11] = ahead.sum(axis=2) / (st.ahead_count[cur] * tab.T)
    out[~valid] = 0.0
    return out.astype(np.float32), valid
