"""POLICY: a learned policy (docs/algorithms/POLICY.md, docs/learning.md). The robot keeps
the beliefs of the learning environment (:class:`~patrolling_sim.learned.beliefs.TeamBeliefs`:
its own visits and the ``[j, MSG_LEARNED_VISIT, v, next]`` messages delivered to it, which it
sends too), builds the slot observation with the environment's own code
(:mod:`patrolling_sim.learned.slots`) and scores the neighbours of its vertex with the
network of a policy file (:mod:`patrolling_sim.learned.policyfile`).

Parameters (``ctx.params``): ``policy`` (path of the ``.npz`` file; default the shipped
``policies/slots_bc.npz``, :data:`DEFAULT_POLICY`), ``policy_mode``
(``greedy``, default: the valid slot of highest score, first on ties; ``sample``: drawn from
the softmax of the scores with ``ctx.rng``), ``start_vertices`` (the team's start vertices,
given by graph mode; unknown teammates count nowhere until they report).
"""
from patrolling_sim.algorithms.base import PatrolStrategy, register
from patrolling_sim.common import paths
from patrolling_sim.common.errors import PatrolInputError
from patrolling_sim.common.protocol import MSG_LEARNED_VISIT
from patrolling_sim.learned.beliefs import TeamBeliefs
from patrolling_sim.learned.observe import GraphTables
from patrolling_sim.learned.policyfile import file_label, load_policy
from patrolling_sim.learned.slots import SlotTables, slot_features

MODES = ("greedy", "sample")
#: the shipped policy used without a ``policy`` param (``policies/<name>.npz``)
DEFAULT_POLICY = "slots_bc"


def policy_path(params) -> str:
    """The policy file of ``params``: its ``policy``, else the shipped default."""
    return (params or {}).get("policy") or paths.policy_file(DEFAULT_POLICY)


def slot_tables_for(pgraph, team_size: int, speed: float) -> SlotTables:
    """The slot observation's tables of ``pgraph`` for a team of ``team_size`` at ``speed``
    (kept with the graph: the agents of one process share them)."""
    key = (team_size, float(speed))
    cache = pgraph.derived.setdefault("learned_slot_tables", {})
    if key not in cache:
        degree = max((len(pgraph.neighbor_ids(v)) for v in range(pgraph.n)), default=1)
        tab = GraphTables(pgraph, team_size, speed, max(degree, 1))
        cache[key] = SlotTables(tab, speed)
    return cache[key]


@register
class LearnedPolicy(PatrolStrategy):
    name = "POLICY"
    params_in_label = True

    @classmethod
    def check_params(cls, params):
        """The policy file loads and fits this code; ``policy_mode`` is known."""
        load_policy(policy_path(params))
        mode = (params or {}).get("policy_mode", "greedy")
        if mode not in MODES:
            raise PatrolInputError(f"POLICY: policy_mode must be one of {', '.join(MODES)}, "
                                   f"got {mode!r}")

    @classmethod
    def content_params(cls, params):
        """The policy file (given or the shipped default) by its label, ``stem@sha8``."""
        return {"policy": file_label(policy_path(params))}

    def __init__(self, ctx):
        super().__init__(ctx)
        self.check_params(ctx.params)
        self.policy = load_policy(policy_path(ctx.params))
        self.algorithm_params = self.policy.label
        self.sample = ctx.params.get("policy_mode", "greedy") == "sample"
        self.slots = slot_tables_for(self.graph, ctx.team_size, self.policy.speed)
        self.beliefs = TeamBeliefs(ctx.team_size, self.graph.n,
                                   ctx.params.get("start_vertices"))

    def start(self, start_vertex, now):
        super().start(start_vertex, now)
        self.beliefs.start(self.id, start_vertex)

    def on_arrival(self, vertex, now):
        super().on_arrival(vertex, now)
        self.beliefs.arrive(self.id, vertex, now)

    def choose_next(self, now):
        feats, mask = slot_features(self.slots, self.beliefs, [self.id], now)
        k = self.policy.choose(feats[0], mask[0], self.rng if self.sample else None)
        return int(self.slots.tab.nbr[self.current, k]) if mask[0].any() else self.current

    def send_results(self, now):
        """Tell the teammates the visit and the next goal (as the learning environment)."""
        if self.next is not None:
            self.send(MSG_LEARNED_VISIT, self.current, self.next)

    def on_message(self, data, now):
        n = self.graph.n
        if len(data) >= 4 and data[1] == MSG_LEARNED_VISIT and 0 <= data[0] < \
                self.ctx.team_size and 0 <= data[2] < n and 0 <= data[3] < n:
            self.beliefs.news(self.id, data[0], data[2], data[3], now)
