"""Post 003's tutorial DQN on S seeds at once, in PyTorch (issue 53): the vectorised engine's core.

Every seed has its own networks, AdamW-with-AMSGrad state, replay memory and CartPole, stacked on
a leading seed axis; one call steps every seed's env once and, as the tutorial's loop body does,
pushes the transition, trains on a batch of 128 drawn without replacement (once the memory holds
128), soft-updates the target and chooses the next action. The update goes through ``torch.func``
(``functional_call``, ``grad_and_value``, ``vmap`` over the seed axis); the optimizer, the soft
update and the env are elementwise over the stacked tensors. The same code runs on a CPU or a
GPU; on a GPU the step can be recorded once as a CUDA graph and replayed (``cuda_graph=True``,
``GraphedStep``): the same kernels, without a launch from the host for each.

What is the tutorial's, and what is not:
- the networks start as the tutorial's do for the same seed (``torch.manual_seed(seed)``, then
  ``DQN(4, 2)`` for the policy and a copy for the target), and the update, AdamW's step, the
  gradient clip, the soft update after every step, epsilon's decay and the budget are its own;
- the random draws are not Python's ``random`` or torch's generator: they are a counter-based
  generator (``SeedStreams``, a hash of the seed, the stream, the step and the lane), so a seed's
  draws are its own and do not depend on how many seeds share the batch or which;
- the reset states are drawn from that generator (uniform on [-0.05, 0.05], as Gymnasium's),
  not from Gymnasium's generator;
- a batch is a uniform draw of 128 distinct memory slots (Floyd's algorithm, ``distinct``), as
  ``random.sample`` is; the order of the 128 within a batch differs, which the mean loss ignores.

So a seed here does not replay the tutorial's episodes; ``results/cartpole/vectorised-torch`` reads
the compiled program against the tutorial's own code on 200 seeds, as the compiled engine was read:
equivalent in success and in episodes to threshold (its ``report.md``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn
from torch.func import functional_call, grad_and_value, stack_module_state, vmap

from keras_rl.torch import save_state
from keras_rl.torch.dqn_tutorial import DQN
from keras_rl.torch.envs import MAX_STEPS, CartPole
from keras_rl.torch.optimizers import not_portable

F = nn.functional

_MASK = 0xFFFFFFFF


def _mul32(x: torch.Tensor, c: int) -> torch.Tensor:
    """``x * c mod 2**32`` for ``x`` and ``c`` below 2**32, in int64 without overflowing it (signed
    overflow is undefined in the C++ a compiled program becomes): c split into 16-bit halves."""
    return ((((x * (c >> 16)) & 0xFFFF) << 16) + x * (c & 0xFFFF)) & _MASK


def _mix(x: torch.Tensor) -> torch.Tensor:
    """A 32-bit integer finaliser (Wellons' "lowbias32") on int64 tensors holding 32-bit values."""
    x = x & _MASK
    x = _mul32(x ^ (x >> 16), 0x7FEB352D)
    x = _mul32(x ^ (x >> 15), 0x846CA68B)
    return x ^ (x >> 16)


class SeedStreams:
    """Counter-based random numbers for S seeds: ``bits(stream, counter, lanes)`` is a hash of
    (seed, stream, counter, lane), 32 uniform bits each, the same whatever else is in the batch
    and on any device (integer arithmetic only)."""

    EXPLORE, ACTION, RESET, SAMPLE = 1, 2, 3, 4

    def __init__(self, seeds: torch.Tensor):
        self.keys = _mix(_mix(seeds.to(torch.int64) & _MASK) ^ 0x5BD1E995)[:, None]  # [S, 1]

    def bits(self, stream: int, counter: torch.Tensor, lanes: int) -> torch.Tensor:
        """``[S, lanes]`` int64 in [0, 2**32); ``counter`` a scalar or one per seed."""
        counter = counter.reshape(-1, 1) if counter.dim() else counter
        lane = torch.arange(lanes, dtype=torch.int64, device=self.keys.device)
        keyed = _mix(self.keys ^ ((stream * 0x9E3779B9) & _MASK))
        return _mix(_mix(keyed + (counter & _MASK)) + _mul32(lane, 0x632BE5AB))

    def uniform64(self, stream: int, counter: torch.Tensor, lanes: int) -> torch.Tensor:
        """``[S, lanes]`` float64 uniform on [0, 1), 53 bits from two hashes."""
        hi = self.bits(stream, counter, 2 * lanes)
        return ((hi[:, :lanes] >> 5) * 67108864 + (hi[:, lanes:] >> 6)).to(torch.float64) / 9007199254740992.0


def distinct(bits: torch.Tensor, n: torch.Tensor | int) -> torch.Tensor:
    """Floyd's algorithm on a seed axis: ``k = bits.shape[1]`` distinct integers of [0, n), each
    k-subset equally likely (as ``random.sample`` draws them), from k columns of 32 random bits.

    Floyd takes, for j = n-k .. n-1, t_j uniform on [0, j] and keeps t_j, or j where t_j is kept
    already. Every t_i drawn before is kept by then, and the j kept instead of a repeat is j itself,
    so t_j is a repeat exactly where an earlier t_i equals it, or where it is an earlier j whose
    own t was a repeat: an OR along a chain of earlier positions, resolved by pointer doubling."""
    seeds, k = bits.shape
    device = bits.device
    j = n - k + torch.arange(k, dtype=torch.int64, device=device)  # [k]
    t = (bits * (j + 1)) >> 32  # uniform on [0, j]
    # an equal t earlier in the row: a stable sort by value puts equal values in draw order
    order = torch.sort(t, dim=1, stable=True)
    same = torch.zeros_like(t, dtype=torch.bool)
    same[:, 1:] = order.values[:, 1:] == order.values[:, :-1]
    repeat = torch.zeros_like(same).scatter(1, order.indices, same)
    link = torch.where(t >= n - k, t - (n - k), -1)  # the earlier position whose j this t is
    for _ in range(max(1, math.ceil(math.log2(k)))):
        live = link >= 0
        at = link.clamp(min=0)
        repeat = repeat | (live & repeat.gather(1, at))
        link = torch.where(live, link.gather(1, at), -1)
    return torch.where(repeat, j, t)


RECOMPILE_LIMIT = 64
"""The fewest programs of the step a process may compile before it fails (``compiled``)."""


def compiled(step, seeds: int):
    """``step`` through ``torch.compile``, one static program per batch size (a batch that sheds
    seeds meets several) and per ``trains``: never a dynamic-shape program, whose rounding may
    differ, and never the eager fallback torch takes silently past its recompile limit, which would
    run another engine's program under this one's name; past the limit it fails instead.

    The limit counts the programs of one code object in one process, and every engine's
    ``_train_step`` is the same code. Its programs are keyed by the shapes of the engine's tensors
    and by its config's values, not by the engine: engines built one after another in a process (a
    pool worker, batch after batch) reuse the programs of the sizes met before with the same config,
    and a config not met before (a sweep's next point) compiles its own. The records keep one length
    (``chunk``; ``keep`` keeps it), so a batch of ``seeds`` compiles at most two programs per size it
    sheds to: each engine raises both of torch's limits (per code object, and over the process) by
    those ``2 * seeds`` (``tests/test_torch_vectorised.py`` runs batch after batch in one process)."""
    config = torch._dynamo.config
    config.recompile_limit = max(config.recompile_limit, RECOMPILE_LIMIT) + 2 * seeds
    config.accumulated_recompile_limit = max(config.accumulated_recompile_limit, config.recompile_limit)
    config.fail_on_recompile_limit_hit = True
    return torch.compile(step, dynamic=False)


class GraphedStep:
    """The training step recorded once as a CUDA graph and replayed for every later training step
    (``VectorisedDQN(..., cuda_graph=True)``): on a GPU the eager step is hundreds of small kernels
    whose launches from the host cost more than the kernels, and a graph launches them all at once
    with no compile. The math is the eager step's, kernel for kernel.

    A graph replays on the tensors it was recorded on, so the step may change none of its state's
    storage: it writes every table, counter and record in place, and the steps that move the clock
    live on the device (the step has no host sync, and the random draws are counter-based, so there
    is no generator state to capture). The first ``WARMUP`` training steps run eagerly on a side
    stream, as torch asks before a capture; they are real steps. The steps before the memory
    trains run eagerly (a different program, played once)."""

    WARMUP = 3

    def __init__(self, step):
        self.step, self.graph, self.warm = step, None, 0
        self.side = torch.cuda.Stream()

    def __call__(self, trains: bool) -> None:
        if not trains:
            self.step(False)
            return
        if self.graph is None:
            if self.warm < self.WARMUP:
                self.side.wait_stream(torch.cuda.current_stream())
                with torch.cuda.stream(self.side):
                    self.step(True)
                torch.cuda.current_stream().wait_stream(self.side)
                self.warm += 1
                return
            self.graph = torch.cuda.CUDAGraph()
            with torch.cuda.graph(self.graph):  # recorded, not run: the replay below runs it
                self.step(True)
        self.graph.replay()


def default_device() -> torch.device:
    """Where the vectorised engine runs: the GPU where torch sees one, else the CPU."""
    return torch.device("cuda" if torch.cuda.is_available() else "cpu")


@dataclass
class EpisodeEnd:
    """A seed's finished episode, as the host reads it after a chunk."""

    seed: int
    episode: int  # 1-based, the seed's own count
    steps: int
    loss_sum: float
    updates: int


class VectorisedDQN:
    """S seeds of post 003's tutorial DQN (``CartPoleDQNConfig``: equal configs but for the seed)
    stepped together on ``device``."""

    def __init__(
        self,
        configs,
        device: str | torch.device = "cpu",
        compile: bool = False,
        cuda_graph: bool = False,
        chunk: int = 1,
    ):
        not_portable("vectorised engine")
        c = self.config = configs[0]
        others = {k: v for k, v in c.to_dict().items() if k != "seed"}
        for other in configs[1:]:
            if {k: v for k, v in other.to_dict().items() if k != "seed"} != others:
                raise ValueError("the seeds of one vectorised batch need the same config but for the seed")
        if c.init != "torch" or getattr(c, "matched_init", False):
            raise ValueError("the vectorised engine starts the tutorial's torch init only (init=torch)")
        self.device = torch.device(device)
        if cuda_graph and (compile or self.device.type != "cuda"):
            raise ValueError("cuda_graph records the eager step on a CUDA device: not with compile, not on a CPU")
        self.cuda_graph = cuda_graph
        self.seeds = [cfg.seed for cfg in configs]
        S, dev = len(configs), self.device
        self.env = CartPole()
        self.max_steps = MAX_STEPS[c.env_id]
        nets = []
        for seed in self.seeds:  # the tutorial's init for this seed: manual_seed, then the policy
            with torch.random.fork_rng(devices=[]):
                torch.manual_seed(seed)
                nets.append(DQN(4, 2, c.q_hidden_units))
        params, _ = stack_module_state(nets)
        self.params = {k: v.detach().to(dev) for k, v in params.items()}
        self.target = {k: v.clone() for k, v in self.params.items()}
        self.exp_avg = {k: torch.zeros_like(v) for k, v in self.params.items()}
        self.exp_avg_sq = {k: torch.zeros_like(v) for k, v in self.params.items()}
        self.max_exp_avg_sq = {k: torch.zeros_like(v) for k, v in self.params.items()}
        self._base = DQN(4, 2, c.q_hidden_units).to("meta")
        cap = c.buffer_size
        self.memory = {
            "state": torch.zeros(S, cap, 4, dtype=torch.float32, device=dev),
            "action": torch.zeros(S, cap, dtype=torch.int64, device=dev),
            "reward": torch.zeros(S, cap, dtype=torch.float32, device=dev),
            "next_state": torch.zeros(S, cap, 4, dtype=torch.float32, device=dev),
            "non_final": torch.zeros(S, cap, dtype=torch.bool, device=dev),
        }
        self.streams = SeedStreams(torch.tensor(self.seeds, device=dev))
        self.t = 0  # env steps every seed has taken (the tutorial's steps_done), on the host
        self.clock = torch.zeros((), dtype=torch.int64, device=dev)  # the same, on the device
        self.chunk_start = torch.zeros((), dtype=torch.int64, device=dev)
        self.episode = torch.zeros(S, dtype=torch.int64, device=dev)  # episodes each seed finished
        self.ep_steps = torch.zeros(S, dtype=torch.int64, device=dev)
        self.ep_loss = torch.zeros(S, dtype=torch.float64, device=dev)
        self.ep_updates = torch.zeros(S, dtype=torch.int64, device=dev)
        self.state = self._reset_states(self.episode)
        self.rows = torch.arange(S, device=dev)
        # a chunk's records, for ``chunk`` steps (the longest chunk the caller plays); play grows
        # them to a longer one and keep keeps their length: a compiled step meets one shape
        self.records = self._records(chunk)
        self._step = compiled(self._train_step, S) if compile else self._train_step
        self._regraph()

    def _regraph(self) -> None:
        """A new CUDA graph, where the engine records one, once the state's tensors were replaced
        (``keep``, larger records): the old graph would replay on the old tensors."""
        if self.cuda_graph:
            self._step = GraphedStep(self._train_step)

    # -- a seed's state ----------------------------------------------------------------------
    _TABLES = ("params", "target", "exp_avg", "exp_avg_sq", "max_exp_avg_sq", "memory")
    _ROWS = ("episode", "ep_steps", "ep_loss", "ep_updates", "state")

    def seed_states(self) -> list[dict]:
        """Each seed's part of the engine between chunks, on the CPU: what its checkpoint keeps.
        A seed's state is its own (its streams are keyed by its seed and the step), so any batch
        of seeds at the same step resumes from these parts, whichever batch they were played in."""
        return [
            {
                "seed": seed,
                "t": self.t,
                **{name: {k: v[i].cpu().clone() for k, v in getattr(self, name).items()} for name in self._TABLES},
                **{name: getattr(self, name)[i].cpu().clone() for name in self._ROWS},
            }
            for i, seed in enumerate(self.seeds)
        ]

    def load_seed_states(self, states: list[dict]) -> None:
        """``seed_states``' parts back, one per seed of this engine and in its order, all taken
        at the same step."""
        if [s["seed"] for s in states] != self.seeds:
            raise ValueError(f"states of seeds {[s['seed'] for s in states]} for an engine of seeds {self.seeds}")
        steps = {int(s["t"]) for s in states}
        if len(steps) != 1:
            raise ValueError(f"the seeds of one batch must resume at the same step, not at {sorted(steps)}")
        for name in self._TABLES:
            for k, v in getattr(self, name).items():
                v.copy_(torch.stack([s[name][k] for s in states]))
        for name in self._ROWS:
            getattr(self, name).copy_(torch.stack([s[name] for s in states]))
        (self.t,) = steps
        self.clock.fill_(self.t)

    def keep(self, lanes: list[int]) -> None:
        """Only the seeds at rows ``lanes`` play on, in that order: every stacked table, counter
        and stream key is cut to them. A seed's state is its own, so the seeds kept play on as
        they would have in the whole batch (a batch sheds the seeds whose runs are done, rather
        than stepping them to the end of its longest seed). The compiled step compiles at most
        twice per batch size it meets (``compiled``); the records keep their length."""
        if not lanes or len(set(lanes)) != len(lanes) or not all(0 <= k < len(self.seeds) for k in lanes):
            raise ValueError(f"lanes {lanes} are not distinct rows of a batch of {len(self.seeds)}")
        at = torch.tensor(lanes, device=self.device)
        for name in self._TABLES:
            setattr(self, name, {k: v.index_select(0, at) for k, v in getattr(self, name).items()})
        for name in self._ROWS:
            setattr(self, name, getattr(self, name).index_select(0, at))
        self.streams.keys = self.streams.keys.index_select(0, at)
        self.seeds = [self.seeds[k] for k in lanes]
        self.rows = torch.arange(len(lanes), device=self.device)
        self.records = self._records(self.records["done"].shape[0])
        self._regraph()

    # -- pieces ------------------------------------------------------------------------------
    def _reset_states(self, episode: torch.Tensor) -> torch.Tensor:
        """Gymnasium CartPole's reset: each state variable uniform on [-0.05, 0.05], float64."""
        u = self.streams.uniform64(SeedStreams.RESET, episode, 4)
        return -0.05 + 0.1 * u

    def _q(self, params, x):
        return functional_call(self._base, params, (x,))

    def _seed_loss(self, params, target, state, action, reward, next_state, non_final):
        c = self.config
        q = self._q(params, state).gather(1, action[:, None])
        with torch.no_grad():
            next_values = torch.where(non_final, self._q(target, next_state).max(1).values, 0.0)
        expected = next_values * c.gamma + reward
        return F.smooth_l1_loss(q, expected[:, None])

    def learn(self, batch, step: torch.Tensor) -> torch.Tensor:
        """The tutorial's ``optimize_model`` from its batches on, for every seed: the Huber loss,
        its gradient, the clip at ``grad_clip_value`` and AdamW's ``step``-th step. ``batch`` is
        [S, 128, ...] states, actions, rewards, next states and non-final flags; the losses, [S]."""
        grads, loss = vmap(grad_and_value(self._seed_loss))(self.params, self.target, *batch)
        self._adamw(grads, step)
        return loss

    def soft_update(self) -> None:
        """``target = policy * TAU + target * (1 - TAU)``, every step, as the tutorial's loop does."""
        tau = self.config.tau
        with torch.no_grad():
            for k, p in self.params.items():
                self.target[k].copy_(p * tau + self.target[k] * (1 - tau))

    def _adamw(self, grads, step: torch.Tensor) -> None:
        """torch's AdamW (decoupled weight decay, AMSGrad), elementwise on the stacked tensors."""
        c = self.config
        beta1, beta2 = 0.9, 0.999
        bias1 = 1 - beta1**step
        bias2_sqrt = torch.sqrt(1 - beta2**step)
        for k, p in self.params.items():
            g = grads[k].clamp(-c.grad_clip_value, c.grad_clip_value)
            p.mul_(1 - c.q_lr * c.weight_decay)
            self.exp_avg[k].lerp_(g, 1 - beta1)
            self.exp_avg_sq[k].mul_(beta2).addcmul_(g, g, value=1 - beta2)
            torch.maximum(self.max_exp_avg_sq[k], self.exp_avg_sq[k], out=self.max_exp_avg_sq[k])
            denom = self.max_exp_avg_sq[k].sqrt() / bias2_sqrt + c.adam_eps
            p.sub_(c.q_lr / bias1 * self.exp_avg[k] / denom)

    def _train_step(self, trains: bool):
        """One env step of every seed: act, step, push, train on a batch of the filled slots where
        ``trains``, soft update, and for the seeds whose episode ended, their record into the
        chunk's records and a reset. The clock is a tensor on the device and every count comes
        from it, so one compiled program serves every step and nothing crosses to the host."""
        c, mem, rec, S = self.config, self.memory, self.records, len(self.seeds)
        t = self.clock  # env steps every seed has taken before this one (the tutorial's steps_done)
        rows = self.rows
        obs = self.env.observe(self.state)
        eps = c.eps_end + (c.eps_start - c.eps_end) * torch.exp(-t.to(torch.float64) / c.eps_decay)
        with torch.no_grad():
            greedy = vmap(self._q)(self.params, obs[:, None, :])[:, 0].argmax(1)
        explore = self.streams.uniform64(SeedStreams.EXPLORE, t, 1)[:, 0]
        coin = self.streams.bits(SeedStreams.ACTION, t, 1)[:, 0] & 1
        action = torch.where(explore > eps, greedy, coin)
        new_state, next_obs, reward, terminated = self.env.step(self.state, action)
        self.ep_steps.add_(1)
        done = terminated | (self.ep_steps >= self.max_steps)
        slot = (t % c.buffer_size).expand(S)
        mem["state"].index_put_((rows, slot), obs)
        mem["action"].index_put_((rows, slot), action)
        mem["reward"].index_put_((rows, slot), reward.to(torch.float32))
        mem["next_state"].index_put_((rows, slot), next_obs)
        mem["non_final"].index_put_((rows, slot), ~terminated)
        if trains:  # the memory holds train_start transitions or more: it did before the push
            filled = torch.clamp(t + 1, max=c.buffer_size)
            picks = distinct(self.streams.bits(SeedStreams.SAMPLE, t, c.batch_size), filled)
            names = ("state", "action", "reward", "next_state", "non_final")
            batch = [mem[name][rows[:, None], picks] for name in names]
            loss = self.learn(batch, (t + 2 - c.train_start).to(torch.float64))
            self.ep_loss.add_(loss.to(torch.float64))
            self.ep_updates.add_(1)
        self.soft_update()
        self.episode.add_(done.to(torch.int64))
        row = (t - self.chunk_start).expand(S)
        rec["done"].index_put_((row, rows), done)
        rec["steps"].index_put_((row, rows), self.ep_steps)
        rec["loss"].index_put_((row, rows), self.ep_loss)
        rec["updates"].index_put_((row, rows), self.ep_updates)
        rec["episode"].index_put_((row, rows), self.episode)
        self.ep_steps.masked_fill_(done, 0)
        self.ep_loss.masked_fill_(done, 0.0)
        self.ep_updates.masked_fill_(done, 0)
        self.state.copy_(torch.where(done[:, None], self._reset_states(self.episode), new_state))
        self.clock.add_(1)

    # -- driving -----------------------------------------------------------------------------
    def _records(self, steps: int) -> dict[str, torch.Tensor]:
        S, dev = len(self.seeds), self.device
        return {
            "done": torch.zeros(steps, S, dtype=torch.bool, device=dev),
            "steps": torch.zeros(steps, S, dtype=torch.int64, device=dev),
            "loss": torch.zeros(steps, S, dtype=torch.float64, device=dev),
            "updates": torch.zeros(steps, S, dtype=torch.int64, device=dev),
            "episode": torch.zeros(steps, S, dtype=torch.int64, device=dev),
        }

    def play(self, steps: int) -> list[EpisodeEnd]:
        """``steps`` env steps of every seed, then one read of what they recorded: the episodes
        that ended, in order."""
        if self.records["done"].shape[0] < steps:  # sized to the longest chunk yet, reused
            self.records = self._records(steps)
            self._regraph()
        self.records["done"][:steps].zero_()
        self.chunk_start.fill_(self.t)
        for _ in range(steps):
            self.t += 1
            self._step(min(self.t, self.config.buffer_size) >= self.config.train_start)
        rec = {k: v[:steps].cpu() for k, v in self.records.items()}  # the chunk's one host read
        return [
            EpisodeEnd(
                self.seeds[int(s)],
                int(rec["episode"][i, s]),
                int(rec["steps"][i, s]),
                float(rec["loss"][i, s]),
                int(rec["updates"][i, s]),
            )
            for i, s in zip(*torch.nonzero(rec["done"], as_tuple=True))
        ]

    # -- one seed's policy, between chunks ------------------------------------------------------
    def policy(self, k: int) -> DQN:
        """Seed ``k``'s policy network as it stands, a module of its own on the CPU: the tutorial's
        ``DQN``, its parameters named as the tutorial's ``policy_net``'s (``layer1.weight`` ...), so
        its state dict is the ``q_network.pt`` that ``keras-rl evaluate`` loads. Built on the meta
        device and given the seed's tensors: no draw from torch's generator."""
        with torch.device("meta"):
            net = DQN(4, 2, self.config.q_hidden_units)
        net.load_state_dict({name: v[k].detach().cpu().clone() for name, v in self.params.items()}, assign=True)
        return net.eval()


class SeedPolicy:
    """One seed's policy between chunks (``VectorisedDQN.policy``): its greedy action, as the
    tutorial agent's ``greedy_action`` picks it, and its ``q_network.pt``."""

    def __init__(self, engine: VectorisedDQN, k: int):
        self.net = engine.policy(k)

    def __call__(self, obs) -> int:
        with torch.no_grad():
            return int(self.net(torch.as_tensor(np.asarray(obs), dtype=torch.float32)[None]).argmax(1))

    def save(self, run_dir: Path) -> None:
        save_state(self.net, Path(run_dir) / "q_network.pt")
