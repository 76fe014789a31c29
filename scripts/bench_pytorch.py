#!/usr/bin/env python3
"""CPU timing of the dual-agent forecaster (crates/echo-models/src/model.rs) in PyTorch.

The same architecture as the candle model — layer for layer, with the same parameter names
(`embed_a.fc1.weight`, `cross.0.b.att.q.bias`, ...) — at random weights: only the shapes and
the operations matter. Two attention variants: explicit matmul/softmax as in the Rust code
(backend "pytorch") and torch.nn.functional.scaled_dot_product_attention ("pytorch-sdpa").

Cases: models d64 (the shipped size) and d256; inference at batch 1 and 16 (input and output
through numpy arrays, as the candle backend goes through slices); one training step at batch
64 (forward of the social and individual forecasts, MSE + MSE + 0.1 bone-length loss,
backward, global grad-norm clip at 1, AdamW step, zero grads).

    .cache/bench-venv/bin/python scripts/bench_pytorch.py --threads 2 --json out.json [--quick]

Prints one line per case and writes {"backend_note": ..., "cases": [...]} (see
scripts/bench_compare.py). Usually run by scripts/bench-vs-pytorch.
"""

import argparse
import json
import math
import os
import struct
import sys
import time

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

OBS, PRED = 8, 23
FRAMES = OBS + PRED
FEATURES = 73
LOCAL_POSE = 66
TEXT_DIM = 384
VELOCITY_PRIOR_S = 0.3
# SMPL 22-joint skeleton (echo_motion::skeleton::PARENTS).
PARENTS = [-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19]
W_BONE = 0.1

MODELS = {
    "d64": dict(d_model=64, heads=4, self_layers=1, temp_mlp=2, rounds=2),
    "d256": dict(d_model=256, heads=16, self_layers=4, temp_mlp=2, rounds=2),
}


def gelu(x):
    # candle's Tensor::gelu is the tanh approximation.
    return F.gelu(x, approximate="tanh")


class Mlp(nn.Module):
    def __init__(self, i, h, o):
        super().__init__()
        self.fc1 = nn.Linear(i, h)
        self.fc2 = nn.Linear(h, o)

    def forward(self, x):
        return self.fc2(gelu(self.fc1(x)))


class Attention(nn.Module):
    def __init__(self, d, heads, sdpa):
        super().__init__()
        self.q = nn.Linear(d, d)
        self.k = nn.Linear(d, d)
        self.v = nn.Linear(d, d)
        self.o = nn.Linear(d, d)
        self.heads = heads
        self.sdpa = sdpa

    def forward(self, x, ctx):
        b, tq, d = x.shape
        tk = ctx.shape[1]
        h = self.heads
        dh = d // h
        q = self.q(x).reshape(b, tq, h, dh).transpose(1, 2)
        k = self.k(ctx).reshape(b, tk, h, dh).transpose(1, 2)
        v = self.v(ctx).reshape(b, tk, h, dh).transpose(1, 2)
        if self.sdpa:
            y = F.scaled_dot_product_attention(q, k, v)
        else:
            att = torch.matmul(q, k.transpose(-2, -1)) / math.sqrt(dh)
            y = torch.matmul(torch.softmax(att, dim=-1), v)
        return self.o(y.transpose(1, 2).reshape(b, tq, d))


class Block(nn.Module):
    """Pre-LN: attention (self or cross) then feed-forward, both residual."""

    def __init__(self, d, heads, sdpa):
        super().__init__()
        self.ln_q = nn.LayerNorm(d, eps=1e-5)
        self.ln_kv = nn.LayerNorm(d, eps=1e-5)
        self.att = Attention(d, heads, sdpa)
        self.ln_ff = nn.LayerNorm(d, eps=1e-5)
        self.ff = Mlp(d, 2 * d, d)

    def forward(self, x, ctx):
        x = x + self.att(self.ln_q(x), self.ln_kv(ctx))
        return x + self.ff(self.ln_ff(x))


class TempMlp(nn.Module):
    """siMLPe temporal block: x + LN_features(Linear_time(x))."""

    def __init__(self, t, d):
        super().__init__()
        self.time = nn.Linear(t, t)
        self.ln = nn.LayerNorm(d, eps=1e-5)

    def forward(self, x):
        y = self.time(x.transpose(1, 2)).transpose(1, 2)
        return x + self.ln(y)


def sinusoidal(t, d):
    pe = torch.zeros(1, t, d)
    for p in range(t):
        for i in range(d // 2):
            w = 1.0 / 10000.0 ** (2.0 * i / d)
            pe[0, p, 2 * i] = math.sin(p * w)
            pe[0, p, 2 * i + 1] = math.cos(p * w)
    return pe


def prior_gain_matrix(pred, features):
    """ForecasterConfig::prior_gain_matrix with velocity_prior_root_only: (pred, features)."""
    r = math.exp(-1.0 / (VELOCITY_PRIOR_S * 15.0))
    gains, acc = [], 0.0
    for k in range(1, pred + 1):
        acc += r**k
        gains.append(acc)
    g = torch.tensor(gains, dtype=torch.float32)[:, None].repeat(1, features)
    if features == FEATURES:
        g[:, :LOCAL_POSE] = 0.0
    return g


class Forecaster(nn.Module):
    def __init__(self, d_model, heads, self_layers, temp_mlp, rounds, sdpa=False):
        super().__init__()
        d = d_model
        t = FRAMES + 1  # + the text token
        self.embed_a = Mlp(FEATURES, d, d)
        self.embed_b = Mlp(FEATURES, d, d)
        self.text = nn.Linear(TEXT_DIM, d)
        self.self = nn.ModuleList(Block(d, heads, sdpa) for _ in range(self_layers))
        self.temp = nn.ModuleList(TempMlp(t, d) for _ in range(temp_mlp))
        self.cross = nn.ModuleList(
            nn.ModuleDict({"a": Block(d, heads, sdpa), "b": Block(d, heads, sdpa)})
            for _ in range(rounds)
        )
        self.decode_a = Mlp(d, d, FEATURES)
        self.decode_b = Mlp(d, d, FEATURES)
        self.register_buffer("pe", sinusoidal(FRAMES, d), persistent=False)
        self.register_buffer("gain", prior_gain_matrix(PRED, FEATURES), persistent=False)

    def forward_pair(self, xa, xb, text, individual=True):
        """xa, xb: (b, obs, F); text: (b, 384) → social [a, b] and individual [a, b]
        forecasts, (b, pred, F) each (individual None unless asked for)."""
        b, n_obs, _ = xa.shape
        tok = self.text(text).unsqueeze(1)  # (b, 1, d)
        agents, bases = [], []
        for x, embed in ((xa, self.embed_a), (xb, self.embed_b)):
            last = x[:, n_obs - 1 : n_obs]  # (b, 1, F)
            padded = torch.cat([x, last.expand(b, FRAMES - n_obs, x.shape[2])], 1)
            h = embed(padded) + self.pe
            h = torch.cat([tok, h], 1)
            for blk in self.self:  # shared by both agents
                h = blk(h, h)
            for tm in self.temp:
                h = tm(h)
            agents.append(h)
            # The base: the last frame plus the damped velocity (root only).
            v = last - x[:, n_obs - 2 : n_obs - 1]
            bases.append(last + v * self.gain)
        ha, hb = agents
        for c in self.cross:  # interleaved refinement
            ha = c["a"](ha, hb)
            hb = c["b"](hb, ha)
        s = 1 + n_obs  # skip the text token and the observed frames

        def dec(mlp, h, base):
            return mlp(h[:, s : s + PRED]) + base

        social = [dec(self.decode_a, ha, bases[0]), dec(self.decode_b, hb, bases[1])]
        indiv = None
        if individual:
            indiv = [
                dec(self.decode_a, agents[0], bases[0]),
                dec(self.decode_b, agents[1], bases[1]),
            ]
        return social, indiv


def bone_lengths(x):
    """(…, F) → (…, 21): bone lengths of the local pose."""
    j = len(PARENTS)
    l = x[..., : 3 * j].reshape(*x.shape[:-1], j, 3)
    child = torch.arange(1, j)
    parent = torch.tensor(PARENTS[1:])
    bones = l.index_select(-2, child) - l.index_select(-2, parent)
    return (bones.square().sum(-1) + 1e-8).sqrt()


def n_params(m):
    return sum(p.numel() for p in m.parameters())


def check_against_checkpoint(model, path):
    """Names and shapes of `model`'s parameters against a candle safetensors checkpoint of the
    same configuration: a mismatch means the mirror is not the Rust model."""
    with open(path, "rb") as f:
        n = struct.unpack("<Q", f.read(8))[0]
        header = json.loads(f.read(n))
    theirs = {k: tuple(v["shape"]) for k, v in header.items() if k != "__metadata__"}
    ours = {k: tuple(p.shape) for k, p in model.named_parameters()}
    if theirs != ours:
        only_t = sorted(set(theirs) - set(ours))[:5]
        only_o = sorted(set(ours) - set(theirs))[:5]
        shapes = [k for k in set(theirs) & set(ours) if theirs[k] != ours[k]][:5]
        sys.exit(
            f"parameters differ from {path}: only there {only_t}, only here {only_o}, "
            f"other shapes {shapes}"
        )
    return sum(math.prod(s) for s in theirs.values())


def time_it(fn, warmup, samples):
    for _ in range(warmup):
        fn()
    v = []
    for _ in range(samples):
        t = time.perf_counter()
        fn()
        v.append((time.perf_counter() - t) * 1e3)
    return float(np.median(v)), v


def bench_inference(model, b, warmup, samples, rng):
    obs = rng.uniform(-1, 1, size=b * 2 * OBS * FEATURES).astype(np.float32)
    text = rng.uniform(-0.1, 0.1, size=b * TEXT_DIM).astype(np.float32)

    def predict():
        # As the candle backend: flat values in, flat values out.
        with torch.inference_mode():
            x = torch.from_numpy(obs).reshape(b, 2, OBS, FEATURES)
            t = torch.from_numpy(text).reshape(b, TEXT_DIM)
            (ya, yb), _ = model.forward_pair(x[:, 0], x[:, 1], t, individual=False)
            return torch.cat([ya.flatten(1), yb.flatten(1)], 1).flatten().numpy()

    assert predict().shape == (b * 2 * PRED * FEATURES,)
    return time_it(predict, warmup, samples)


def bench_train(model, b, warmup, samples, rng):
    obs = torch.from_numpy(rng.standard_normal((b, 2, OBS, FEATURES), dtype=np.float32))
    fut = torch.from_numpy(rng.standard_normal((b, 2, PRED, FEATURES), dtype=np.float32))
    text = torch.from_numpy(rng.uniform(-0.1, 0.1, (b, TEXT_DIM)).astype(np.float32))
    opt = torch.optim.AdamW(model.parameters(), lr=1e-3, weight_decay=0.01)
    model.train()

    def step():
        (sa, sb), (ia, ib) = model.forward_pair(obs[:, 0], obs[:, 1], text)
        soc = torch.stack([sa, sb], 1)
        ind = torch.stack([ia, ib], 1)
        loss = (
            F.mse_loss(soc, fut)
            + F.mse_loss(ind, fut)
            + W_BONE * F.mse_loss(bone_lengths(soc), bone_lengths(fut))
        )
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
        opt.step()
        opt.zero_grad()
        l = loss.item()
        assert math.isfinite(l), l

    return time_it(step, warmup, samples)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--threads", type=int, default=2, help="torch intra-op threads")
    ap.add_argument("--json", required=True, help="where to write the results")
    ap.add_argument("--quick", action="store_true", help="a fifth of the samples")
    ap.add_argument("--models", default="d64,d256", help="comma-separated, of d64,d256")
    ap.add_argument(
        "--checkpoint",
        default="models/forecaster.safetensors",
        help="d64's parameter names and shapes are checked against it when it exists",
    )
    args = ap.parse_args()

    torch.set_num_threads(args.threads)
    torch.manual_seed(1)
    rng = np.random.default_rng(1)
    div = 5 if args.quick else 1

    # Samples per (model, kind, batch).
    plan = {
        "d64": [("inference", 1, 500), ("inference", 16, 200), ("train-step", 64, 30)],
        "d256": [("inference", 1, 200), ("inference", 16, 50), ("train-step", 64, 10)],
    }
    note = f"pytorch {torch.__version__}, {torch.get_num_threads()} threads"
    print(f"{note}; {os.cpu_count()} CPUs; median of the samples in ms", flush=True)
    load_start = os.getloadavg()[0]
    cases = []
    for name in args.models.split(","):
        cfg = MODELS[name]
        m = Forecaster(**cfg)
        line = f"{name}: {cfg}, {n_params(m)} parameters"
        if name == "d64" and os.path.exists(args.checkpoint):
            line += f" (= {args.checkpoint}: {check_against_checkpoint(m, args.checkpoint)})"
        print(line, flush=True)
        for kind, b, n in plan[name]:
            n = max(n // div, 2)
            for backend, sdpa in (("pytorch", False), ("pytorch-sdpa", True)):
                torch.manual_seed(1)
                model = Forecaster(**cfg, sdpa=sdpa)
                if kind == "inference":
                    model.eval()
                    med, _ = bench_inference(model, b, 10, n, rng)
                else:
                    med, _ = bench_train(model, b, 3 if not args.quick else 2, n, rng)
                cases.append(
                    dict(model=name, batch=b, kind=kind, backend=backend,
                         median_ms=round(med, 4), samples=n)
                )
                print(f"{name:<5} {kind:<10} batch {b:<3} {backend:<13} n={n:<4} "
                      f"median {med:9.3f} ms", flush=True)

    os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
    with open(args.json, "w") as f:
        # The 1-minute load average before and after: other work on the machine skews timings.
        loadavg = [round(load_start, 2), round(os.getloadavg()[0], 2)]
        json.dump({"backend_note": note, "loadavg": loadavg, "cases": cases}, f, indent=1)
        f.write("\n")
    print(f"wrote {args.json} (load average {loadavg[0]} before, {loadavg[1]} after)")


if __name__ == "__main__":
    main()
