"""The outbound walk of the original CGG's route construction (step 4 of
:mod:`patrolling_sim.planning.cyclic_route`): the main route with detours over the edges it
misses, read as the original reads its fixed arrays (docs/fidelity.md, CGG).

:func:`outbound_walk` follows the main route; where a vertex has an unused edge off it, it
inserts a detour of at most ``num_arcs`` new vertices that walks back to where it left. The
original's ``desvio`` (the detour), ``regresso`` (its way back) and ``lista`` (a vertex's
candidate neighbours) are arrays shared by every detour of one walk, so a slot an earlier
detour wrote and this one did not reads the earlier value; an array overrun raises
IndexError (:func:`~patrolling_sim.planning.cyclic_route.cyclic_route` reports it as a
:class:`RouteConstructionError`).

The walk works on the cyclic route's graph structure (``n``, ``nb``, ``vis``, ``odd``,
``clear``, ``slot``, ``set_arc``, ``free``), whose flags it sets and whose count of reads
of memory the original never wrote it advances.
"""
from typing import List, Sequence, Tuple

#: steps allowed to one search (a walk, an outbound walk) before giving up
MAX_STEPS = 2_000_000
#: neighbour slots per vertex in the original's graph structure
SLOTS = 8


class RouteConstructionError(RuntimeError):
    """The construction cannot produce a route (see
    :mod:`patrolling_sim.planning.cyclic_route`)."""


def _on_route_edge(a, b, cp):
    """True if a-b are consecutive somewhere on the main route."""
    for i, v in enumerate(cp):
        if v == a and ((i > 0 and cp[i - 1] == b) or (i < len(cp) - 1 and cp[i + 1] == b)):
            return True
    return False


def outbound_walk(web, cp: Sequence[int], num_arcs: int) -> Tuple[List[int], bool]:
    """The main route ``cp`` with detours of at most ``num_arcs`` new vertices (flags
    cleared first). Returns (walk, every edge walked). The detour and return lists are the
    original's fixed arrays, read as it reads them (unwritten slots hold -1).

    Raises:
        RouteConstructionError: the walk reads memory that cannot be modelled, or exceeds
            ``MAX_STEPS`` steps.
        IndexError: a detour overruns one of the original's arrays.
    """
    web.clear()
    return _OutboundWalk(web, list(cp), num_arcs).run()


class _OutboundWalk:
    """One outbound walk: the original's arrays (shared by all its detours), its step count,
    and the cursor of the detour under way (``ult``: the main-route vertex it left, ``prox``:
    the vertex reached, ``no_ant``: the one before, ``j``: the original's reused slot index,
    ``i_d`` / ``i_r``: the fill of ``desvio`` / ``regresso``, ``arcs``: new vertices so far,
    ``on_cp``: the next step reaches the main route, ``leave``: close by the way back)."""

    def __init__(self, web, cp: List[int], num_arcs: int):
        self.web, self.cp, self.num_arcs = web, cp, num_arcs
        self.desvio = [-1] * (web.n * 5 + 8)
        self.regresso = [-1] * (web.n + 8)
        self.lista = [-1] * SLOTS
        self.steps = 0
        self.ult = self.prox = self.no_ant = -1
        self.j = self.arcs = self.i_d = self.i_r = 0
        self.on_cp = self.leave = False

    def run(self) -> Tuple[List[int], bool]:
        """Walk the main route, detouring where a vertex has an unused edge off it. Returns
        (walk, every edge walked)."""
        web, cp = self.web, self.cp
        ida = [cp[0]]
        idx_cp, idx_viz_cp = 0, -1
        while idx_cp < len(cp) - 1:
            ult = cp[idx_cp]
            prox, j, idx_viz_cp = self._next_arc(ult, idx_cp, idx_viz_cp)
            if prox == cp[idx_cp + 1]:                  # stay on the main route
                web.set_arc(ult, web.nb[ult][idx_viz_cp], True, both_all=True)
                ida.append(prox)
                idx_cp += 1
                if prox == cp[-1]:
                    break
                continue
            ida.extend(self._detour(ult, prox, j))
            self._count_step()
        return ida, all(all(row) for row in web.vis)

    def _count_step(self):
        """Count one step; raises RouteConstructionError past ``MAX_STEPS``."""
        self.steps += 1
        if self.steps > MAX_STEPS:
            raise RouteConstructionError("CGG route: detour step bound exceeded")

    def _next_arc(self, ult, idx_cp, idx_viz_cp):
        """Scan ``ult``'s list for its first unused arc off the main route. Returns (that
        neighbour, its slot, ``idx_viz_cp``) or, if there is none, (the route's next vertex,
        the list's length, the last slot holding that vertex; ``idx_viz_cp`` unchanged if
        none does)."""
        web, nxt = self.web, self.cp[idx_cp + 1]
        j = 0
        while j < len(web.nb[ult]):
            w = web.nb[ult][j]
            if not web.vis[ult][j] and not _on_route_edge(ult, w, self.cp):
                return w, j, idx_viz_cp
            if w == nxt:
                idx_viz_cp = j
            j += 1
        return nxt, j, idx_viz_cp

    def _detour(self, ult, prox, j) -> List[int]:
        """The original's detour from ``ult`` through ``prox`` (slot ``j`` of ult's list).
        Returns the vertices it walks after ``ult``, its last one back on the main route."""
        self.ult, self.prox, self.no_ant, self.j = ult, prox, ult, j
        self.arcs, self.i_d, self.i_r = 0, 1, 0
        self.desvio[0] = ult
        self.on_cp = self.web.nb[ult][j] in self.cp
        self.leave = self.on_cp
        while self.arcs < self.num_arcs:
            self._count_step()
            direct, idx_reg = self._arrive()
            self._record_arrival()
            if self.on_cp:                              # reached the main route: step back
                if self.i_r <= 0:
                    raise RouteConstructionError("CGG route: empty return list read")
                self._append(self.regresso[self.i_r - 1])
                self.i_r -= 1
                self.no_ant, self.prox = self.prox, self.no_ant
            self.on_cp = False
            if self.arcs >= self.num_arcs:
                if direct and self.i_r > 0:             # straight back to ult
                    self._close_direct(idx_reg)
                    break
                self.leave = True
            else:
                self._advance()
            if self.leave:                              # the way back closes the detour
                for i in range(self.i_r - 1, -1, -1):
                    self._append(self.regresso[i])
                break
        return self.desvio[1:self.i_d]

    def _append(self, v):
        """Write ``v`` to the detour's next slot."""
        self.desvio[self.i_d] = v
        self.i_d += 1

    def _arrive(self):
        """Flag the arc prox -> no_ant if unused (and then no_ant's free arcs to its slot
        ``j`` neighbour, as the original does). Returns (direct, idx_reg): whether ``ult`` is
        in prox's list, and its last slot there (-1 if not)."""
        web, prox, no_ant = self.web, self.prox, self.no_ant
        direct, marked, idx_reg = False, False, -1
        for i, w in enumerate(web.nb[prox]):
            if w == no_ant and not web.vis[prox][i]:
                web.vis[prox][i] = True
                marked = True
            if w == self.ult:
                direct, idx_reg = True, i
        if marked:
            target = web.slot(no_ant, self.j)
            for i, w in enumerate(web.nb[no_ant]):
                if w == target and not web.vis[no_ant][i]:
                    web.vis[no_ant][i] = True
        return direct, idx_reg

    def _record_arrival(self):
        """Write ``prox`` to the detour; a new vertex counts one arc and pushes ``no_ant`` on
        the way back, a repeated one pushes it only if prox does not neighbour the way
        back's top (an empty way back reads -1 there)."""
        self.desvio[self.i_d] = self.prox
        if self.prox in self.desvio[:max(self.i_d - 1, 0)]:
            back = self.regresso[self.i_r - 1] if self.i_r > 0 else -1
            self.web.odd += self.i_r <= 0
            if back not in self.web.nb[self.prox]:
                self.regresso[self.i_r] = self.no_ant
                self.i_r += 1
        else:
            self.regresso[self.i_r] = self.no_ant
            self.i_r += 1
            self.arcs += 1
        self.i_d += 1

    def _close_direct(self, idx_reg):
        """End the detour with the edge prox-ult: flag prox's slot ``idx_reg`` (an odd read if
        past its list) and ult's arcs to prox, and write ult."""
        web, prox = self.web, self.prox
        if idx_reg < len(web.vis[prox]):
            web.vis[prox][idx_reg] = True
        else:
            web.odd += 1
        for i, w in enumerate(web.nb[self.ult]):
            if w == prox:
                web.vis[self.ult][i] = True
        self._append(self.ult)

    def _advance(self):
        """Take the detour's next step from ``prox``: to its candidate neighbour with fewest
        unused arcs, or, at a dead end, back along the way back."""
        i_list = self._candidates()
        if i_list == 1 and self.lista[0] in self.cp:
            self.on_cp = True
        if i_list <= 0:
            self._dead_end()
        else:
            self._choose(i_list)

    def _candidates(self) -> int:
        """Fill ``lista`` with prox's neighbours over unused arcs off the main route, then
        drop main-route vertices from it as the original does (reading stale slots past the
        fill). Returns the fill; raises RouteConstructionError past ``SLOTS``."""
        web, prox, cp, lista = self.web, self.prox, self.cp, self.lista
        i_list = 0
        for i, w in enumerate(web.nb[prox]):
            if not web.vis[prox][i] and not _on_route_edge(prox, w, cp):
                lista[i_list] = w
                i_list += 1
        i = 0
        while i_list > 1:
            if i >= SLOTS:
                raise RouteConstructionError("CGG route: neighbour list overrun")
            web.odd += i >= i_list
            if lista[i] in cp:
                lista[i:i_list - 1] = lista[i + 1:i_list]
                i_list -= 1
            i += 1
            if i == i_list:
                break
        return i_list

    def _dead_end(self):
        """Walk back along the way back to a vertex with a free arc and resume from its first
        place on the detour; set ``leave`` instead if that vertex is the way back's first
        entry or there is none. Raises RouteConstructionError if that place's successor slot
        was never written."""
        web, desvio, regresso = self.web, self.desvio, self.regresso
        i = self.i_r - 1
        while i >= 0:
            self.j = web.free(regresso[i])
            if self.j > 0:
                break
            self._append(regresso[i])
            self.i_r -= 1
            i -= 1
        if i <= 0:
            self.leave = True
            return
        self.j = 0
        while self.j < self.i_d:
            if desvio[self.j] == regresso[i]:
                self.prox, self.no_ant = desvio[self.j], desvio[self.j + 1]
                if self.no_ant < 0:
                    raise RouteConstructionError("CGG route: unwritten detour slot read")
                break
            self.j += 1
        self.i_r = i

    def _choose(self, i_list):
        """Step to the only candidate, or to the first with fewest unused arcs; ``j`` becomes
        its first unused slot in prox's list (the list's length if none)."""
        web, lista = self.web, self.lista
        if i_list == 1:
            chosen = lista[0]
        else:
            least = None
            for i in range(i_list):
                free = web.free(lista[i])
                if least is None or free < least:
                    chosen, least = lista[i], free
        self.j = 0
        while self.j < len(web.nb[self.prox]):
            if web.nb[self.prox][self.j] == chosen and not web.vis[self.prox][self.j]:
                break
            self.j += 1
        self.no_ant, self.prox = self.prox, chosen
