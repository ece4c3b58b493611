#!/usr/bin/python3
"""Train a slot policy for the POLICY strategy: PPO with one network shared by every
neighbour slot of every robot, on random graphs in the learning environment, warm-started by
imitating a hand-written rule; the policy kept is the best on fixed validation graphs.
Writes ``--out`` (the policy file), ``<out stem>.png`` (training curve) and ``<out
stem>.yaml`` (configuration and figures). Seeded. The method, the reward and the exact
command of the shipped policy: docs/learning.md, "Training a policy". Run with the
workspace's venv (gymnasium, pettingzoo; torch from Debian's python3-torch)::

    .venv/bin/python scripts/train_policy.py --out policies/mine.npz
"""
import glob
import os
import sys
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
for _pkg in ("spqrel_nav_lite", "patrolling_sim"):   # the workspace's packages, unsourced
    _src = os.path.join(ROOT, "src", _pkg, "src")
    if _src not in sys.path:
        sys.path.insert(0, _src)
for _site in glob.glob(os.path.join(ROOT, ".venv", "lib", "python3*", "site-packages")):
    if _site not in sys.path:
        sys.path.append(_site)                        # gymnasium, pettingzoo (make setup)

import numpy as np  # noqa: E402
import yaml  # noqa: E402

from patrolling_sim.common.cli import CliParser, run_main  # noqa: E402
from patrolling_sim.common.errors import PatrolInputError  # noqa: E402
from patrolling_sim.learned.policyfile import save_policy  # noqa: E402
from patrolling_sim.learned.slots import K, SLOT_FEATURES  # noqa: E402

RANDOM_DEFAULT = "random:n=30,size=40,radius=12,max_degree=4,spacing=3"
VALIDATION_SEED = 1_000_000


#: numeric options: (flag, type, default, help)
NUMERIC = (("--duration", float, 1200.0, "sim s per episode"),
           ("--iterations", int, 60, "PPO iterations (0: the warm start alone)"),
           ("--episodes", int, 4, "episodes per iteration"),
           ("--hidden", int, 32, "width of the two hidden layers"),
           ("--lr", float, 1e-3, "Adam learning rate"),
           ("--gamma", float, 0.3, "discount per T of simulated time"),
           ("--lam", float, 0.95, "GAE lambda"),
           ("--clip", float, 0.2, "PPO clip range"),
           ("--epochs", int, 4, "PPO epochs per iteration"),
           ("--minibatch", int, 512, "transitions per minibatch"),
           ("--entropy", float, 0.01, "entropy bonus"),
           ("--warm-start", int, 20, "episodes of imitation of the hand-written rule (0: none)"),
           ("--eval-every", int, 5, "iterations between validations"),
           ("--eval-graphs", int, 1, "validation graphs per map form and team size"),
           ("--seed", int, 0, "seed of everything"))


def build_parser():
    ap = CliParser(prog="train_policy.py", description=(
        "Train a slot policy for --alg POLICY with PPO on random graphs (docs/learning.md)."))
    ap.add_argument("--out", required=True, help="policy file to write (.npz)")
    ap.add_argument("--maps", nargs="+", default=[RANDOM_DEFAULT],
                    help="environment maps drawn per episode (random graph forms or maps)")
    ap.add_argument("--validate-on", nargs="+", default=[], metavar="MAP",
                    help="maps for validation only")
    ap.add_argument("--robots", type=int, nargs="+", default=[2, 4, 6, 8],
                    help="team sizes drawn per episode")
    for flag, typ, default, text in NUMERIC:
        ap.add_argument(flag, type=typ, default=default, help=f"{text} (default {default})")
    ap.add_argument("--quiet", action="store_true")
    ap.add_argument("--reward", default="avg_idleness", choices=("avg_idleness", "visit"),
                    help="the environment's reward summed between a robot's decisions")
    return ap


def check_args(a):
    """One-line errors (PatrolInputError) for bad arguments."""
    def fail(name, what):
        raise PatrolInputError(f"argument --{name.replace('_', '-')}: must be {what}, got "
                               f"{getattr(a, name)}")
    for name in ("episodes", "hidden", "epochs", "minibatch", "eval_graphs", "eval_every"):
        if getattr(a, name) < 1:
            fail(name, ">= 1")
    for name in ("iterations", "warm_start", "entropy"):
        if getattr(a, name) < 0:
            fail(name, ">= 0")
    for name in ("duration", "lr"):
        if not getattr(a, name) > 0:
            fail(name, "> 0")
    for name in ("gamma", "lam", "clip"):
        if not 0 < getattr(a, name) <= 1:
            fail(name, "in (0, 1]")
    if min(a.robots) < 1:
        fail("robots", "team sizes >= 1")
    if not a.out.endswith(".npz"):
        raise PatrolInputError(f"argument --out: expected a .npz file name, got '{a.out}'")
    folder = os.path.dirname(os.path.abspath(a.out))
    if not os.path.isdir(folder) or not os.access(folder, os.W_OK):
        raise PatrolInputError(f"argument --out: folder {folder} does not exist or is not "
                               f"writable")


def make_envs(a):
    """({(map, robots): PatrolParallelEnv} of training (every --maps form and team size),
    the same of validation: every --maps form and --validate-on map with the smallest and
    the largest team size); slot observation."""
    from patrolling_sim.envs.parallel import PatrolParallelEnv
    sizes = sorted(set(a.robots))
    train = {(m, n): PatrolParallelEnv(map=m, robots=n, duration=a.duration,
                                       observation="slots", reward=a.reward)
             for m in a.maps for n in sizes}
    val = {(m, n): train.get((m, n)) or PatrolParallelEnv(
        map=m, robots=n, duration=a.duration, observation="slots", reward=a.reward)
        for m in a.maps + a.validate_on for n in (sizes[0], sizes[-1])}
    return train, val


class Nets:
    """The actor (slot scorer, shipped) and the critic (training only), in torch."""

    def __init__(self, torch, hidden, lr):
        nn = torch.nn
        self.torch = torch
        self.actor = nn.Sequential(nn.Linear(K, hidden), nn.Tanh(), nn.Linear(hidden, hidden),
                                   nn.Tanh(), nn.Linear(hidden, 1))
        self.embed = nn.Sequential(nn.Linear(K, hidden), nn.Tanh())
        self.value_head = nn.Sequential(nn.Linear(2 * hidden, hidden), nn.Tanh(),
                                        nn.Linear(hidden, 1))
        self.opt = torch.optim.Adam([*self.actor.parameters(), *self.embed.parameters(),
                                     *self.value_head.parameters()], lr=lr)

    def numpy_weights(self):
        """[(W (in, out), b)] of the actor, as float64 numpy arrays."""
        lin = [m for m in self.actor if isinstance(m, self.torch.nn.Linear)]
        return [(m.weight.detach().double().numpy().T.copy(),
                 m.bias.detach().double().numpy().copy()) for m in lin]

    def logits(self, x, mask):
        s = self.actor(x).squeeze(-1)
        return s.masked_fill(~mask, -1e9)

    def value(self, x, mask):
        h = self.embed(x)
        m = mask.unsqueeze(-1).float()
        mean = (h * m).sum(1) / m.sum(1).clamp(min=1.0)
        mx = h.masked_fill(~mask.unsqueeze(-1), -1e9).max(1).values
        return self.value_head(self.torch.cat([mean, mx], -1)).squeeze(-1)


def np_scores(weights, x):
    """The actor's slot scores in numpy (the same arithmetic as the policy file's)."""
    last = len(weights) - 1
    for k, (W, b) in enumerate(weights):
        x = x @ W + b
        if k < last:
            x = np.tanh(x)
    return x[..., 0]


def episode(env, weights, rng, seed, greedy=False):
    """Run one episode; returns (per-robot trajectories [[(obs, mask, action, time / T)]],
    per-robot
    rewards [[r]] (r_k: the rewards between decision k and the robot's next one), the
    time-averaged idleness of the run (s, from the steps' instantaneous average idleness))."""
    obs, infos = env.reset(seed=seed)
    n = len(env.possible_agents)
    traj = [[] for _ in range(n)]
    rews = [[] for _ in range(n)]
    acc = [0.0] * n
    area = 0.0
    while env.agents:
        acts = {}
        for a in env.agents:
            if not infos[a]["ready"]:
                continue
            mask = infos[a]["action_mask"].astype(bool)
            s = np.where(mask, np_scores(weights, obs[a].astype(np.float64)), -np.inf)
            if greedy:
                k = int(np.argmax(s))
            else:
                p = np.exp(s - s.max())
                p /= p.sum()
                k = int(rng.choice(len(p), p=p))
            acts[a] = k
            i = env.agent_ids[a]
            traj[i].append((obs[a], mask, k, infos[a]["time"] / env.tab.T))
            if len(traj[i]) >= 2 and env.opt.reward != "visit":
                rews[i].append(acc[i])      # the rewards since its previous decision
            acc[i] = 0.0
        obs, rewards, _, _, infos = env.step(acts)
        for a, r in rewards.items():
            i = env.agent_ids[a]
            if env.opt.reward == "visit":
                if a in acts and len(traj[i]) >= 2:   # this decision reported the last visit
                    rews[i].append(r)
            else:
                acc[i] += r
        info = next(iter(infos.values()), None)
        if info is not None:
            area += info["metrics"]["avg_idleness"] * info["dt"]
    return traj, rews, area / env.opt.duration


def batch_from(trajs, rews, nets, a):
    """Flat arrays (obs, mask, action, advantage, return) of the decisions that have a
    reward (each robot's last decision has none and is dropped), GAE per robot, discounted
    by ``gamma`` per T of simulated time (a decision that comes sooner is not worth more)."""
    torch = nets.torch
    obs, masks, acts, advs, rets = [], [], [], [], []
    for traj, rew in zip(trajs, rews):
        m = len(rew)
        if m == 0:
            continue
        x = np.stack([t[0] for t in traj[:m + 1]]).astype(np.float32)
        mk = np.stack([t[1] for t in traj[:m + 1]])
        with torch.no_grad():
            v = nets.value(torch.from_numpy(x), torch.from_numpy(mk)).numpy()
        times = np.array([t[3] for t in traj[:m + 1]])
        disc = a.gamma ** np.diff(times)
        adv = np.zeros(m)
        gae = 0.0
        for k in range(m - 1, -1, -1):
            delta = rew[k] + disc[k] * v[k + 1] - v[k]
            gae = delta + disc[k] * a.lam * gae
            adv[k] = gae
        obs.append(x[:m])
        masks.append(mk[:m])
        acts.append(np.array([t[2] for t in traj[:m]]))
        advs.append(adv)
        rets.append(adv + v[:m])
    D = max(x.shape[1] for x in obs)                  # graphs of different largest degrees
    obs = [np.pad(x, ((0, 0), (0, D - x.shape[1]), (0, 0))) for x in obs]
    masks = [np.pad(x, ((0, 0), (0, D - x.shape[1]))) for x in masks]
    return [np.concatenate(z) for z in (obs, masks, acts, advs, rets)]


def ppo_update(nets, batch, a, rng):
    """PPO epochs over ``batch``; returns the last minibatch's losses (policy, value)."""
    torch = nets.torch
    obs, masks, acts, advs, rets = (torch.from_numpy(np.asarray(z)) for z in batch)
    obs, acts = obs.float(), acts.long()
    advs = ((advs - advs.mean()) / (advs.std() + 1e-8)).float()
    rets = rets.float()
    with torch.no_grad():
        old = torch.log_softmax(nets.logits(obs, masks), -1).gather(1, acts[:, None])[:, 0]
    n = len(acts)
    lp = lv = 0.0
    for _ in range(a.epochs):
        order = rng.permutation(n)
        for s in range(0, n, a.minibatch):
            idx = torch.from_numpy(order[s:s + a.minibatch])
            logp_all = torch.log_softmax(nets.logits(obs[idx], masks[idx]), -1)
            logp = logp_all.gather(1, acts[idx, None])[:, 0]
            ratio = torch.exp(logp - old[idx])
            adv = advs[idx]
            pl = -torch.min(ratio * adv, ratio.clamp(1 - a.clip, 1 + a.clip) * adv).mean()
            probs = logp_all.exp() * masks[idx]
            ent = -(probs * logp_all.masked_fill(~masks[idx], 0.0)).sum(-1).mean()
            vl = ((nets.value(obs[idx], masks[idx]) - rets[idx]) ** 2).mean()
            loss = pl + 0.5 * vl - a.entropy * ent
            nets.opt.zero_grad()
            loss.backward()
            nets.opt.step()
            lp, lv = float(pl), float(vl)
    return lp, lv


def validate(envs, weights, a):
    """Mean time-averaged idleness / T (the environment's time scale: every team size weighs
    the same) of greedy episodes in the validation environments ``envs`` (validation seeds
    of the random graphs; maps with their start positions)."""
    vals = []
    for (m, n), env in sorted(envs.items()):
        for k in range(a.eval_graphs):
            idle = episode(env, weights, None, VALIDATION_SEED + k, greedy=True)[2]
            vals.append(idle / env.tab.T)
    return float(np.mean(vals))


def rule_weights():
    """The hand-written rule as a linear scorer: idleness - 2 x mates_heading."""
    W = np.zeros((K, 1))
    W[SLOT_FEATURES.index("idleness"), 0] = 1.0
    W[SLOT_FEATURES.index("mates_heading"), 0] = -2.0
    return [(W, np.zeros(1))]


def warm_start(nets, envs, keys, a, rng):
    """Imitation of the hand-written rule (:func:`rule_weights`) on ``a.warm_start`` episodes
    it drives: cross-entropy of the actor's softmax on the rule's greedy choices."""
    torch = nets.torch
    rule = rule_weights()
    steps = []
    for _ in range(a.warm_start):
        env = envs[keys[int(rng.integers(len(keys)))]]
        traj, _, _ = episode(env, rule, rng, int(rng.integers(VALIDATION_SEED)), greedy=True)
        steps += [t for tr in traj for t in tr]
    xs, ms, ys = [t[0] for t in steps], [t[1] for t in steps], [t[2] for t in steps]
    D = max(x.shape[0] for x in xs)
    x = torch.from_numpy(np.stack([np.pad(v, ((0, D - v.shape[0]), (0, 0))) for v in xs]))
    m = torch.from_numpy(np.stack([np.pad(v, (0, D - v.shape[0])) for v in ms]))
    y = torch.from_numpy(np.asarray(ys)).long()
    opt = torch.optim.Adam(nets.actor.parameters(), lr=a.lr)
    for _ in range(a.epochs * 10):
        order = torch.from_numpy(rng.permutation(len(y)))
        for s in range(0, len(y), a.minibatch):
            idx = order[s:s + a.minibatch]
            loss = torch.nn.functional.cross_entropy(nets.logits(x[idx], m[idx]), y[idx])
            opt.zero_grad()
            loss.backward()
            opt.step()
    with torch.no_grad():
        agree = (nets.logits(x, m).argmax(-1) == y).float().mean()
    return len(y), float(agree)


def save_outputs(a, best, curve, evals, wall):
    """The policy file (``best``: (iteration, actor weights) of the lowest validation
    figure), the curve PNG and the configuration YAML; returns the label."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    stem = os.path.splitext(a.out)[0]
    summary = dict({k: v for k, v in vars(a).items() if k != "quiet"},
                   algorithm="PPO, parameter sharing over robots and slots",
                   decisions=int(sum(c[1] for c in curve)), wall_s=round(wall, 1),
                   kept_iteration=best[0])
    label = save_policy(a.out, best[1],
                        {"observation": "slots", "activation": "tanh", "speed": 1.0,
                         "features": list(SLOT_FEATURES), "training": summary})
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.5))
    ax[0].plot([c[0] for c in curve], [c[2] for c in curve], lw=1)
    ax[1].plot([e[0] for e in evals], [e[1] for e in evals], marker="o", lw=1)
    ax[0].set(xlabel="iteration", ylabel=f"mean reward per decision ({a.reward})")
    ax[1].set(xlabel="iteration", ylabel="validation time-avg idleness / T, greedy")
    fig.suptitle(f"{os.path.basename(a.out)} ({label})", fontsize=9)
    fig.tight_layout(), fig.savefig(stem + ".png", dpi=80)
    plt.close(fig)
    summary.update(label=label, validation=[[int(i), round(v, 4)] for i, v in evals])
    with open(stem + ".yaml", "w", encoding="utf-8") as f:
        yaml.safe_dump(summary, f, sort_keys=False)
    return label


def train(a, envs, val):
    """The training loop in ``envs``, validated in ``val`` (:func:`make_envs`); returns the
    policy's label."""
    import torch
    torch.manual_seed(a.seed)
    torch.set_num_threads(1)
    rng = np.random.default_rng(a.seed)
    keys = sorted(envs)
    nets = Nets(torch, a.hidden, a.lr)
    curve, evals = [], []
    t0 = time.monotonic()
    if a.warm_start:
        n, agree = warm_start(nets, envs, keys, a, rng)
        if not a.quiet:
            print(f"warm start: {n} decisions of the rule, agreement {agree:.3f}", flush=True)
    evals.append((0, validate(val, nets.numpy_weights(), a)))
    best = (0, nets.numpy_weights(), evals[-1][1])
    for it in range(1, a.iterations + 1):
        weights = nets.numpy_weights()
        trajs, rews = [], []
        for _ in range(a.episodes):
            env = envs[keys[int(rng.integers(len(keys)))]]
            tr, rw, _ = episode(env, weights, rng, int(rng.integers(VALIDATION_SEED)))
            trajs += tr
            rews += rw
        batch = batch_from(trajs, rews, nets, a)
        mean_r = float(np.mean(np.concatenate([np.asarray(r) for r in rews if r])))
        lp, lv = ppo_update(nets, batch, a, rng)
        curve.append((it, len(batch[2]), mean_r))
        line = f"iter {it}: {len(batch[2])} decisions, reward {mean_r:.4f}, loss {lp:.3f}/{lv:.3f}"
        if it % a.eval_every == 0 or it == a.iterations:
            evals.append((it, validate(val, nets.numpy_weights(), a)))
            line += f", validation {evals[-1][1]:.4f}"
            if evals[-1][1] < best[2]:
                best = (it, nets.numpy_weights(), evals[-1][1])
            save_outputs(a, best, curve, evals, time.monotonic() - t0)   # a checkpoint
        if not a.quiet:
            print(f"{line} ({time.monotonic() - t0:.0f} s)", flush=True)
    return save_outputs(a, best, curve, evals, time.monotonic() - t0)


def main(argv):
    a = build_parser().parse_args(argv)
    check_args(a)
    try:
        import torch  # noqa: F401
    except ImportError:
        raise PatrolInputError("torch is missing: install Debian's python3-torch "
                               "(scripts/packages.txt) and run with .venv/bin/python") from None
    envs, val = make_envs(a)            # a bad map or team size fails here, in one line
    label = train(a, envs, val)
    print(f"policy: {a.out} ({label}); curve {os.path.splitext(a.out)[0]}.png")
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main, "train_policy.py"))
