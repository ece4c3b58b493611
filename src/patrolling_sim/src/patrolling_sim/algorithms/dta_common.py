"""Shared pieces of the DTA family (Farinelli, Iocchi, Nardi, "Distributed on-line dynamic
task assignment for multi-robot patrolling", Autonomous Robots 41(6), 2017): a global
idleness *estimate* that ages with time and is merged from teammates' type-40 messages."""
from .. import paths
from ..dta_params import load_dta_params
from .base import INT16_MAX, MSG_DTA_IDLENESS

INT16_CAP = 32000


class IdlenessEstimate:
    """``gi[v]``: estimated idleness (s) of every vertex, advanced lazily to the clock."""

    def __init__(self, n, initial, now):
        self.values = [float(initial)] * n
        self.t = now

    def advance(self, now):
        dt = now - self.t
        if dt > 0:
            self.values = [g + dt for g in self.values]
            self.t = now
        return self.values

    def merge(self, received, now):
        """Take the smaller of own and received (message payload is 10 x seconds)."""
        g = self.advance(now)
        for k, r in enumerate(received[:len(g)]):
            g[k] = min(g[k], r / 10.0)

    def encode(self, now, zero=None):
        """Payload ``I_0..I_{V-1}`` (int(10*gi), values above int16 replaced by 32000)."""
        out = []
        for k, g in enumerate(self.advance(now)):
            x = 0 if k == zero else int(10 * g)
            out.append(INT16_CAP if x > INT16_MAX else x)
        return out


def dta_params(ctx, file_name, defaults):
    """DTA parameters: ``ctx.params['dta_params']`` file if given, else the shipped
    ``params/DTA/<file_name>.params``; keys missing from the file read as 0 (the original's
    rule), keys missing from both the file and ``defaults``' keys are ignored."""
    path = ctx.params.get("dta_params") or paths.dta_params_file(file_name)
    got = load_dta_params(path)
    return {k: float(got.get(k, 0.0)) for k in defaults}


def decode_idleness(data, n):
    """(values, next) from ``[id, 40, I_0..I_{n-1}, next]``, or None if malformed."""
    if len(data) != n + 3 or data[1] != MSG_DTA_IDLENESS:
        return None
    return data[2:2 + n], data[2 + n]
