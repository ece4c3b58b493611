"""Observations and global state of the learning environment (docs/learning.md, "Spaces"),
built with a few numpy operations for all robots at once from the beliefs of
:class:`~patrolling_sim.learned.beliefs.TeamBeliefs`; the slot observation, which the
``POLICY`` strategy also uses, is in :mod:`patrolling_sim.learned.slots`.

Scales: lengths are divided by ``S`` (the larger side of the graph's bounding box, m), times
by ``T`` (total undirected edge length / (speed x robots): the idleness a team that shared
the edges evenly would keep).

Flat observation of robot i (``neighbour`` actions), F = 3 + 5 D + 5 (N - 1) values:
``[x, y, ready]`` (own vertex, /S) then, for each neighbour slot k < D of its vertex,
``[valid, idleness, length, dx, dy]`` (believed idleness /T, edge length and offset /S; zeros
for empty slots), then for each teammate j != i in id order ``[dx, dy, next_dx, next_dy,
age]`` (offset of the vertex j last reported and of the one it said it heads to, /S, both
its start vertex until it reports; age of that news /T). With ``goal`` actions the believed
idleness of every vertex (/T) and a one-hot of the own vertex follow (F + 2 V).

Graph observation: node features ``[idleness, own, slot, dx, dy, mates_at, mates_heading]``
per vertex (believed idleness /T; 1 on the own vertex; (k + 1) / D on the neighbour of slot k;
offset /S; teammates believed on / heading to the vertex), one edge per directed arc with
its length /S.
"""
from array import array

import numpy as np

#: bounds of every Box (finite, as RL libraries prefer; no feature comes near them)
BOUND = 1e9
NODE_FEATURES = 7
TEAMMATE_FEATURES = 5
SLOT_FEATURES = 5


class GraphTables:
    """Per-graph arrays the observations read (built once per graph)."""

    def __init__(self, pgraph, robots: int, speed: float, max_degree: int):
        g = self.pgraph = pgraph
        self.n = g.n
        self.pos = np.asarray(g.pos, dtype=float)
        ext = self.pos.max(axis=0) - self.pos.min(axis=0) if g.n > 1 else np.ones(2)
        self.S = float(max(ext.max(), 1.0))
        total = sum(g.arc_cost(u, w) for u in range(g.n) for w in g.neighbor_ids(u)
                    if u < w) * g.resolution
        self.T = max(total / (speed * robots), 1.0)
        self.D = max_degree
        self.nbr = np.full((g.n, max_degree), -1, dtype=np.int64)
        self.nbr_len = np.zeros((g.n, max_degree))
        self.degree = np.zeros(g.n, dtype=np.int64)
        for v in range(g.n):
            ids = g.neighbor_ids(v)
            self.degree[v] = len(ids)
            for k, w in enumerate(ids):
                self.nbr[v, k] = w
                self.nbr_len[v, k] = g.arc_cost(v, w) * g.resolution
        self.valid = self.nbr >= 0
        self.safe_nbr = np.where(self.valid, self.nbr, 0)
        links = [(u, w) for u in range(g.n) for w in g.neighbor_ids(u)]
        self.edge_links = np.asarray(links, dtype=np.int64).reshape(-1, 2)
        self.edge_feat = np.asarray([[g.arc_cost(u, w) * g.resolution / self.S]
                                     for u, w in links], dtype=np.float32).reshape(-1, 1)
        self.reachable = np.isfinite(np.asarray(g.dist))
        self.mask_neighbour = self.valid.astype(np.int8)
        self.mask_goal = self.reachable.astype(np.int8)
        #: the rows of the two masks (one view each, handed out as they are)
        self.mask_neighbour_rows = list(self.mask_neighbour)
        self.mask_goal_rows = list(self.mask_goal)
        #: each vertex's neighbours in the graph file's order (plain lists)
        self.nbr_lists = [[int(w) for w in g.neighbor_ids(v)] for v in range(g.n)]
        # constant parts of the flat observation, gathered by vertex
        self.own_xy = self.pos / self.S
        self.offset = (self.pos[None, :, :] - self.pos[:, None, :]) / self.S   # [a, b]: b - a
        self.static_slots = np.zeros((g.n, max_degree, SLOT_FEATURES))
        self.static_slots[:, :, 0] = self.valid
        self.static_slots[:, :, 2] = self.nbr_len / self.S
        self.static_slots[:, :, 3:5] = self.offset[np.arange(g.n)[:, None], self.safe_nbr]
        self.static_slots[~self.valid] = 0.0
        self.valid_over_T = self.valid / self.T
        self._rows = {}
        # the first 3 + 5 D values of a robot's flat observation and their time
        # coefficients, by vertex (the idleness entries are filled per robot)
        width = 3 + SLOT_FEATURES * max_degree
        self.static_row = np.zeros((g.n, width))
        self.static_row[:, 0:2] = self.own_xy
        self.static_row[:, 3:] = self.static_slots.reshape(g.n, -1)
        self.coef_row = np.zeros((g.n, width))
        self.coef_row[:, 4::SLOT_FEATURES] = self.valid_over_T
        self.slot_cols = [{int(w): 4 + SLOT_FEATURES * k
                           for k, w in enumerate(self.nbr[v, :self.degree[v]])}
                          for v in range(g.n)]
        self.static_row_mv = [memoryview(r) for r in self.static_row]
        self.coef_row_mv = [memoryview(r) for r in self.coef_row]
        self.offset_list = [[tuple(p) for p in rows] for rows in self.offset.tolist()]
        self._dist_m = None
        self.mean_edge = float(self.nbr_len[self.valid].mean()) if self.valid.any() else 1.0

    @property
    def dist_m(self):
        """(V, V) shortest-path lengths in metres (inf if unreachable; computed on first use)."""
        if self._dist_m is None:
            self._dist_m = np.asarray(self.pgraph.dist, dtype=float) * self.pgraph.resolution
        return self._dist_m

    def rows(self, N):
        """(N, 1) row indices."""
        return np.arange(N)[:, None]

    def others(self, N):
        """(N, N - 1): for each robot, the ids of the others in order (cached)."""
        if N not in self._rows:
            self._rows[N] = np.array([[j for j in range(N) if j != i] for i in range(N)],
                                     dtype=np.int64).reshape(N, N - 1)
        return self._rows[N]

    def flat_size(self, robots: int, goal: bool) -> int:
        return flat_size(robots, self.D, self.n, goal)


def flat_size(robots: int, max_degree: int, n_vertices: int, goal: bool) -> int:
    """Length of the flat observation (module docstring)."""
    size = 3 + SLOT_FEATURES * max_degree + TEAMMATE_FEATURES * (robots - 1)
    return size + 2 * n_vertices if goal else size


class FlatObservations:
    """The flat observations of every robot, kept up to date event by event: ``base`` and
    ``coef`` (N, F) with observation = ``base + now * coef`` (every time-dependent feature
    is ``(now - t_event) / T``: ``base`` holds ``-t_event / T``, ``coef`` ``1 / T``). The
    board calls :meth:`rebuild` when a robot reached a vertex and :meth:`news` when a
    teammate's report was delivered (with whether a believed visit time changed); a
    step then costs a few array operations whatever the team size. At these sizes one
    numpy call costs more than a few scalar writes: the per-event work is plain Python,
    reading and writing single values through memoryviews of the rows."""

    def __init__(self, tab: GraphTables, board, goal: bool):
        N = board.last_visit.shape[0]
        self.tab, self.board, self.goal, self.N = tab, board, goal, N
        F = tab.flat_size(N, goal)
        self.base = np.zeros((N, F))
        self.coef = np.zeros((N, F))
        self._buf = np.empty((N, F))
        self.base_rows = list(self.base)              # row views, one per robot
        self.base_mv = [memoryview(row) for row in self.base_rows]
        self.coef_rows = list(self.coef)
        self.coef_mv = [memoryview(row) for row in self.coef_rows]
        self.lv_rows = list(board.last_visit)
        self.lv_mv = [memoryview(row) for row in self.lv_rows]
        self.inv_t = -1.0 / tab.T
        self.mate0 = 3 + SLOT_FEATURES * tab.D
        self.goal0 = self.mate0 + TEAMMATE_FEATURES * (N - 1)
        self.others = tab.others(N)
        #: column of teammate j's block in robot i's row
        self.mate_col = [{int(j): self.mate0 + TEAMMATE_FEATURES * k
                          for k, j in enumerate(self.others[i])} for i in range(N)]
        self.others_list = self.others.tolist()
        self.slot_col = [{} for _ in range(N)]
        self.coef[:, self.mate0 + 4:self.goal0:TEAMMATE_FEATURES] = 1.0 / tab.T
        if goal:
            self.coef[:, self.goal0:self.goal0 + tab.n] = 1.0 / tab.T
        for i in range(N):
            self.rebuild(i)

    def rebuild(self, i: int) -> None:
        """Robot ``i``'s row from scratch (its vertex changed)."""
        tab, b = self.tab, self.board
        cur = int(b.current[i])
        m0, g0 = self.mate0, self.goal0
        lvm, rowm = self.lv_mv[i], self.base_mv[i]
        rowm[0:m0] = tab.static_row_mv[cur]
        self.coef_mv[i][0:m0] = tab.coef_row_mv[cur]
        inv_t = self.inv_t
        cols = self.slot_col[i] = tab.slot_cols[cur]
        for w, col in cols.items():
            rowm[col] = lvm[w] * inv_t
        off = tab.offset_list[cur]
        mv, mn, mt = b.mate_vertex[i], b.mate_next[i], b.mate_time[i]
        vals = []
        for j in self.others_list[i]:
            vals += off[mv[j]]
            vals += off[mn[j]]
            vals.append(mt[j] * inv_t)
        rowm[m0:g0] = array("d", vals)
        if self.goal:
            row = self.base_rows[i]
            V = tab.n
            row[g0:g0 + V] = self.lv_rows[i] * inv_t
            row[g0 + V:] = 0.0
            row[g0 + V + cur] = 1.0

    def news(self, i: int, j: int, v: int, nxt: int, t: float, fresher: bool) -> None:
        """Robot ``i`` heard at ``t`` that teammate ``j`` reached ``v`` and heads to ``nxt``;
        ``fresher``: i now believes v was visited at ``t``."""
        row = self.base_mv[i]
        value = -t / self.tab.T
        if fresher:
            col = self.slot_col[i].get(v)
            if col is not None:
                row[col] = value
            if self.goal:
                row[self.goal0 + v] = value
        col = self.mate_col[i][j]
        off = self.tab.offset_list[self.board.current[i]]
        row[col], row[col + 1] = off[v]
        row[col + 2], row[col + 3] = off[nxt]
        row[col + 4] = value

    def receiver(self, i: int):
        """``f(j, v, nxt, now)``: the board's ``news(i, j, v, nxt, now)`` (the beliefs of
        robot ``i``, then :meth:`news`) in one call, the same operations in the same order."""
        b, tab = self.board, self.tab
        lvm, rowm = self.lv_mv[i], self.base_mv[i]
        mate_vertex, mate_next, mate_time = b.mate_vertex[i], b.mate_next[i], b.mate_time[i]
        slot_col, mate_col, current = self.slot_col, self.mate_col[i], b.current
        offsets, T, goal0 = tab.offset_list, tab.T, self.goal0 if self.goal else None

        def news(j, v, nxt, now):
            fresher = now > lvm[v]
            if fresher:
                lvm[v] = now
            mate_vertex[j] = v
            mate_next[j] = nxt
            mate_time[j] = now
            value = -now / T
            if fresher:
                col = slot_col[i].get(v)
                if col is not None:
                    rowm[col] = value
                if goal0 is not None:
                    rowm[goal0 + v] = value
            col = mate_col[j]
            off = offsets[current[i]]
            rowm[col], rowm[col + 1] = off[v]
            rowm[col + 2], rowm[col + 3] = off[nxt]
            rowm[col + 4] = value
        return news

    def observe(self, now: float, ready) -> np.ndarray:
        """(N, F) float32 observations at ``now``; ``ready``: N floats (1: must decide)."""
        buf = self._buf
        np.multiply(self.coef, now, out=buf)
        buf += self.base                 # base + now * coef, the same sum either way round
        out = buf.astype(np.float32)
        out[:, 2] = ready
        return out


def graph_observation(tab: GraphTables, board, now: float, i: int):
    """(nodes (V, NODE_FEATURES) float32, edges (E, 1) float32, edge_links (E, 2)) of robot
    ``i`` (module docstring)."""
    nodes = np.zeros((tab.n, NODE_FEATURES), dtype=np.float32)
    v = board.current[i]
    nodes[:, 0] = (now - board.last_visit[i]) / tab.T
    nodes[v, 1] = 1.0
    deg = tab.degree[v]
    nodes[tab.nbr[v, :deg], 2] = (np.arange(deg) + 1.0) / tab.D
    nodes[:, 3:5] = (tab.pos - tab.pos[v]) / tab.S
    for j in range(len(board.mate_vertex)):
        if j != i:
            nodes[board.mate_vertex[i][j], 5] += 1.0
            nodes[board.mate_next[i][j], 6] += 1.0
    return nodes, tab.edge_feat, tab.edge_links


def state_vector(tab: GraphTables, true_last_visit, now: float, positions, alive, ready):
    """The global state (V + 4 N float32): true idleness of every vertex /T, then per robot
    ``[x, y, alive, ready]`` (true position /S)."""
    idle = (now - np.asarray(true_last_visit, dtype=float)) / tab.T
    robots = np.column_stack([np.asarray(positions, dtype=float) / tab.S,
                              np.asarray(alive, dtype=float), np.asarray(ready, dtype=float)])
    return np.concatenate([np.maximum(idle, 0.0), robots.ravel()]).astype(np.float32)
