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
    (m/s): the two-hop neighbourhoods and the distances in mean edge lengths."""

    def __init__(self, tab, speed: float):
        self.tab = tab
        V, D = tab.n, tab.D
        self.L = max(tab.mean_edge, 1e-9)
        self.length = tab.nbr_len / self.L
        self.travel = tab.nbr_len / (speed * tab.T)
        nb = tab.safe_nbr                                    # (V, D)
        ahead = tab.nbr[nb]                                  # (V, D, D): w's neighbours
        self.ahead_valid = (tab.valid[nb] & (ahead != np.arange(V)[:, None, None])
                            & tab.valid[:, :, None])
        self.ahead_idx = np.where(self.ahead_valid, ahead, 0).reshape(V, D * D)
        self.ahead_count = np.maximum(self.ahead_valid.sum(axis=2), 1)
        self.degree = tab.degree[nb] / 4.0
        d = np.asarray(tab.dist_m, dtype=float) / self.L
        self.dist = np.where(np.isfinite(d), d, 1e6)         # (V, V)


def slot_features(st: SlotTables, beliefs, ids, now: float):
    """(features (R, D, K) float32, mask (R, D) bool) of robots ``ids`` (R of them) at time
    ``now`` from ``beliefs`` (:class:`~patrolling_sim.learned.beliefs.TeamBeliefs`); module
    docstring."""
    tab = st.tab
    ids = np.asarray(ids, dtype=np.int64)
    R, D = len(ids), tab.D
    cur = np.asarray([beliefs.current[i] for i in ids], dtype=np.int64)
    nbr = tab.safe_nbr[cur]                                  # (R, D)
    valid = tab.valid[cur]
    lv = beliefs.last_visit[ids]                             # (R, V)
    idl = np.where(valid, now - np.take_along_axis(lv, nbr, 1), 0.0)
    top = idl.max(axis=1, keepdims=True)
    out = np.zeros((R, D, K))
    out[:, :, 0] = valid
    out[:, :, 1] = idl / tab.T
    out[:, :, 2] = np.where(top > 0, idl / np.where(top > 0, top, 1.0), 1.0)
    out[:, :, 3] = idl >= top - 1e-9
    out[:, :, 4] = st.length[cur]
    out[:, :, 5] = st.travel[cur]
    mv = np.asarray([beliefs.mate_vertex[i] for i in ids], dtype=np.int64)   # (R, N)
    mn = np.asarray([beliefs.mate_next[i] for i in ids], dtype=np.int64)
    known = (mn >= 0) & (np.arange(mn.shape[1])[None, :] != ids[:, None])
    mv = np.where(known, mv, -1)
    mn = np.where(known, mn, -1)
    out[:, :, 6] = (mn[:, None, :] == nbr[:, :, None]).sum(axis=2)
    out[:, :, 7] = (mv[:, None, :] == nbr[:, :, None]).sum(axis=2)
    d = st.dist[nbr[:, :, None], np.where(known, mn, 0)[:, None, :]]     # (R, D, N)
    d = np.where(known[:, None, :], d, np.inf)
    out[:, :, 8] = np.exp(-d).sum(axis=2)
    out[:, :, 9] = np.minimum(d.min(axis=2, initial=np.inf), FAR)
    ai = st.ahead_idx[cur]                                   # (R, D * D)
    ahead = (now - np.take_along_axis(lv, ai, 1)).reshape(R, D, D) / tab.T
    ahead = np.where(st.ahead_valid[cur], ahead, 0.0)
    out[:, :, 10] = ahead.max(axis=2)
    out[:, :, 11] = ahead.sum(axis=2) / st.ahead_count[cur]
    out[:, :, 12] = st.degree[cur]
    out[~valid] = 0.0
    return out.astype(np.float32), valid
