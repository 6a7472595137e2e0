#!/usr/bin/python3
"""The PyTorch peer of ropes_nn_bench: the same networks and training steps, timed the same
way, printed as "name images_per_second" lines. Run by ropes_nn_bench with
LD_PRELOAD=libtcmalloc_minimal.so.4 (Debian libtcmalloc-minimal4), which made PyTorch several
times faster here than glibc's allocator, and 2 threads.

    torch_peer.py [--quick] [--threads N]
"""
import argparse
import statistics
import time

import torch
import torch.nn as nn
import torch.nn.functional as F


class SameConv(nn.Module):
    """Conv with Flax/JAX SAME padding (smaller half before)."""

    def __init__(self, cin, cout, k, stride=1):
        super().__init__()
        self.conv, self.k, self.s = nn.Conv2d(cin, cout, k, stride), k, stride

    def forward(self, x):
        h = x.shape[-1]
        out = (h + self.s - 1) // self.s
        total = max((out - 1) * self.s + self.k - h, 0)
        return self.conv(F.pad(x, (total // 2, total - total // 2, total // 2, total - total // 2)))


class ResBlockGN(nn.Module):
    def __init__(self, c):
        super().__init__()
        g = min(32, c)
        self.n1, self.c1 = nn.GroupNorm(g, c, eps=1e-6), SameConv(c, c, 3)
        self.n2, self.c2 = nn.GroupNorm(g, c, eps=1e-6), SameConv(c, c, 3)

    def forward(self, x):
        return x + self.c2(F.relu(self.n2(self.c1(F.relu(self.n1(x))))))


def stage(cin, w):
    return [SameConv(cin, w, 3), ResBlockGN(w), ResBlockGN(w)]


def ae1(m):
    w = [max(1, int(x * m)) for x in (64, 128, 256, 512)]
    enc, c = [], 1
    for i in range(4):
        enc += stage(c, w[i]) + [SameConv(w[i], w[i] if i < 3 else 1, 3, 2), nn.ReLU()]
        c = w[i]
    dec, c = [], 1
    for i in (3, 2, 1, 0):
        dec += stage(c, w[i]) + [nn.ConvTranspose2d(w[i], w[i], 4, 2, 1), nn.ReLU()]
        c = w[i]
    dec += [SameConv(c, 1, 3), nn.ReLU()]
    return nn.Sequential(*enc), nn.Sequential(*dec)


def ldr(cin):
    return nn.Sequential(nn.Conv2d(cin, 32, 3), nn.ReLU(), nn.Conv2d(32, 64, 3), nn.ReLU(),
                         nn.Conv2d(64, 128, 3), nn.ReLU(), nn.Flatten(), nn.Linear(512, 128),
                         nn.ReLU(), nn.Linear(128, 1))


class Ae2(nn.Module):
    def __init__(self, m, cin, latent):
        super().__init__()
        w = [max(1, int(x * m)) for x in (64, 128, 256)]
        enc, c = [], cin
        for i in range(3):
            enc += stage(c, w[i]) + [SameConv(w[i], w[i], 3, 2), nn.ReLU()]
            c = w[i]
        self.enc, self.to_latent = nn.Sequential(*enc), nn.Linear(w[2], latent)
        self.from_latent, self.bottleneck = nn.Linear(latent, w[2]), w[2]
        d = [max(1, int(x * m)) for x in (512, 256, 128)]
        dec, c = [], w[2]
        for i in range(3):
            dec += stage(c, d[i]) + [nn.ConvTranspose2d(d[i], d[i], 4, 2, 1), nn.ReLU()]
            c = d[i]
        dec += [SameConv(c, cin, 3), nn.ReLU()]
        self.dec = nn.Sequential(*dec)

    def encode(self, y):
        return self.to_latent(self.enc(y).flatten(1))

    def decode(self, z):
        return self.dec(F.relu(self.from_latent(z)).reshape(z.shape[0], self.bottleneck, 1, 1))


def timed(step, batch, repeats):
    step()  # warm up
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        step()
        times.append(time.perf_counter() - t0)
    return batch / statistics.median(times)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    repeats = 3 if args.quick else 7

    for m, label in ((1 / 8, "ae1_x1/8"), (1 / 4, "ae1_x1/4")):
        enc, dec = ae1(m)
        opt = torch.optim.Adam(list(enc.parameters()) + list(dec.parameters()), lr=1e-4)
        x = torch.rand(32, 1, 128, 128)

        def step():
            opt.zero_grad()
            F.mse_loss(dec(enc(x)), x).backward()
            opt.step()
        print(f"{label}_train {timed(step, 32, repeats):.2f}", flush=True)
        with torch.no_grad():
            one = x[:1]
            print(f"{label}_encode_latency_ms {1000 / timed(lambda: enc(one), 1, repeats * 5):.3f}",
                  flush=True)

    net = ldr(2)
    opt = torch.optim.Adam(net.parameters(), lr=1e-3)
    y, t = torch.randn(64, 2, 8, 8), (torch.rand(64, 1) > 0.5).float()

    def ldr_step():
        opt.zero_grad()
        F.binary_cross_entropy_with_logits(net(y), t).backward()
        opt.step()
    print(f"ldr_train {timed(ldr_step, 64, repeats * 3):.2f}", flush=True)

    for m, label in ((1 / 8, "ae2_x1/8"), (1 / 4, "ae2_x1/4")):
        ae = Ae2(m, 2, 6)
        opt = torch.optim.Adam(ae.parameters(), lr=7e-5)
        y, v = torch.randn(64, 2, 8, 8), torch.randn(64, 2, 8, 8)
        target = torch.zeros(6)
        target[1] = 1

        def ae2_step():
            opt.zero_grad()
            z = ae.encode(y)
            recon = ae.decode(z)
            jtv = torch.autograd.grad(recon, z, v, create_graph=True)[0]
            loss = F.mse_loss(recon, y) + ((jtv.abs().mean(0) - target) ** 2).sum()
            loss.backward()
            opt.step()
        print(f"{label}_sparsity_train {timed(ae2_step, 64, repeats):.2f}", flush=True)


if __name__ == "__main__":
    main()
