#!/usr/bin/python3
"""The PyTorch peer of ropes_crl_bench: the same networks (built from the same ropes_crl
specs, which ropes_crl_bench writes to a JSON file of cases), the same batches and steps,
timed the same way (the median of the repeats after one warm-up), printed as "name value"
lines. ropes_crl_bench runs it at its best: tcmalloc preloaded, OPENBLAS_NUM_THREADS=1,
OPENBLAS_CORETYPE unset, the same thread count.

    torch_peer.py CASES.json --threads N

SAME padding where it is symmetric (stride 1, odd kernel) can be PyTorch's own (native) or
an explicit F.pad before an unpadded convolution; PyTorch 1.13 picks different kernels for
the two (here the explicit one encodes a single image about 2.4 times faster; for training
steps they are within noise), so each case runs both ways and reports its better figure, and
"NAME:native_padding 1|0" says which it was. Asymmetric SAME (stride 2) is always an
explicit pad of the smaller half before, as ropes_nn pads.
"""
import argparse
import json
import statistics
import time

import torch
import torch.nn as nn
import torch.nn.functional as F


NATIVE_PADDING = True  # the variant being timed (see the module's docstring)
SYMMETRIC_CONVS = 0  # convolutions built whose padding the variant changes


class Conv(nn.Module):
    """ropes_nn's Conv2d: SAME (smaller half before) or VALID padding."""

    def __init__(self, cin, cout, k, stride=1, valid=False):
        super().__init__()
        self.k, self.s, self.valid = k, stride, valid
        global SYMMETRIC_CONVS
        symmetric = not valid and stride == 1 and k % 2 == 1
        SYMMETRIC_CONVS += int(symmetric)
        self.native = valid or (NATIVE_PADDING and symmetric)
        pad = 0 if valid or not self.native else k // 2
        self.conv = nn.Conv2d(cin, cout, k, stride, padding=pad)

    def forward(self, x):
        if self.native:
            return self.conv(x)
        h = x.shape[-1]
        out = (h + self.s - 1) // self.s
        total = max((out - 1) * self.s + self.k - h, 0)
        return self.conv(F.pad(x, (total // 2, total - total // 2, total // 2, total - total // 2)))


class ResBlockGN(nn.Module):
    def __init__(self, c):
        super().__init__()
        g = min(32, c)
        self.n1, self.c1 = nn.GroupNorm(g, c, eps=1e-6), Conv(c, c, 3)
        self.n2, self.c2 = nn.GroupNorm(g, c, eps=1e-6), Conv(c, c, 3)

    def forward(self, x):
        return x + self.c2(F.relu(self.n2(self.c1(F.relu(self.n1(x))))))


def stage(cin, w, blocks):
    return [Conv(cin, w, 3)] + [ResBlockGN(w) for _ in range(blocks)]


class Ae1(nn.Module):
    """ropes_crl::Ae1 from its spec."""

    def __init__(self, s):
        super().__init__()
        patchify = s["stem"] == "patchify"
        enc, c = [], 1
        if patchify:
            enc.append(Conv(1, s["stem_channels"], s["stem_factor"], s["stem_factor"], valid=True))
            c = s["stem_channels"]
        widths = s["widths"]
        for i, w in enumerate(widths):
            last = i + 1 == len(widths)
            enc += stage(c, w, s["blocks_per_stage"]) + [
                Conv(w, s["code_channels"] if last else w, 3, 2), nn.ReLU()]
            c = w
        dec, c = [], s["code_channels"]
        for w in reversed(widths):
            dec += stage(c, w, s["blocks_per_stage"]) + [nn.ConvTranspose2d(w, w, 4, 2, 1), nn.ReLU()]
            c = w
        if patchify:
            dec.append(nn.ConvTranspose2d(c, 1, s["stem_factor"], s["stem_factor"]))
        else:
            dec.append(Conv(c, 1, 3))
        dec.append(nn.ReLU())
        self.enc, self.dec = nn.Sequential(*enc), nn.Sequential(*dec)

    def forward(self, x):
        return self.dec(self.enc(x))


def ldr(s):
    layers, c, side = [], s["in_channels"], s["input_size"]
    for w in s["widths"]:
        layers += [nn.Conv2d(c, w, 3), nn.ReLU()]
        c, side = w, side - 2
    return nn.Sequential(*layers, nn.Flatten(), nn.Linear(c * side * side, s["hidden"]), nn.ReLU(),
                         nn.Linear(s["hidden"], 1))


class Ae2(nn.Module):
    """ropes_crl::Ae2 from its spec: the MLP or the convolutional kind."""

    def __init__(self, s):
        super().__init__()
        self.s = s
        cin, side = s["in_channels"], s["input_size"]
        act = nn.SiLU if s["activation"] == "silu" else nn.ReLU
        if s["kind"] == "mlp":
            enc, c = [nn.Flatten()], cin * side * side
            for w in s["widths"]:
                enc += [nn.Linear(c, w), act()]
                c = w
            enc.append(nn.Linear(c, s["latent_dim"]))
            dec, c = [], s["latent_dim"]
            for w in reversed(s["widths"]):
                dec += [nn.Linear(c, w), act()]
                c = w
            dec.append(nn.Linear(c, cin * side * side))
            self.enc, self.dec = nn.Sequential(*enc), nn.Sequential(*dec)
            return
        enc, c = [], cin
        for w in s["widths"]:
            enc += stage(c, w, s["blocks_per_stage"]) + [Conv(w, w, 3, 2), nn.ReLU()]
            c = w
        self.enc, self.to_latent = nn.Sequential(*enc), nn.Linear(c, s["latent_dim"])
        self.from_latent, self.bottleneck = nn.Linear(s["latent_dim"], c), c
        dec = []
        for w in s["decoder_widths"]:
            dec += stage(c, w, s["blocks_per_stage"]) + [nn.ConvTranspose2d(w, w, 4, 2, 1), nn.ReLU()]
            c = w
        dec += [Conv(c, cin, 3), nn.ReLU()]
        self.dec = nn.Sequential(*dec)

    def encode(self, y):
        if self.s["kind"] == "mlp":
            return self.enc(y)
        return self.to_latent(self.enc(y).flatten(1))

    def decode(self, z):
        n, s = z.shape[0], self.s
        if s["kind"] == "mlp":
            return self.dec(z).reshape(n, s["in_channels"], s["input_size"], s["input_size"])
        return self.dec(F.relu(self.from_latent(z)).reshape(n, self.bottleneck, 1, 1))


def timed(step, repeats):
    step()  # warm up
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        step()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def code_shape(spec, n):
    return (n, spec["in_channels"], spec["input_size"], spec["input_size"])


def run(case):
    kind, b, reps = case["kind"], case["batch"], case["repeats"]
    if kind == "ae1_train":
        net = Ae1(case["ae1"])
        opt = torch.optim.Adam(net.parameters(), lr=1e-4)
        x = torch.rand(b, 1, case["ae1"]["image_size"], case["ae1"]["image_size"])

        def step():
            opt.zero_grad()
            F.mse_loss(net(x), x).backward()
            opt.step()
        return b / timed(step, reps)
    if kind in ("ae1_encode", "ae1_encode_latency"):
        net = Ae1(case["ae1"])
        x = torch.rand(b, 1, case["ae1"]["image_size"], case["ae1"]["image_size"])
        with torch.no_grad():
            s = timed(lambda: net.enc(x), reps)
        return 1000 * s if kind == "ae1_encode_latency" else b / s
    if kind == "ldr_train":
        net = ldr(case["ldr"])
        opt = torch.optim.Adam(net.parameters(), lr=1e-3)
        y, t = torch.randn(code_shape(case["ldr"], b)), (torch.rand(b, 1) > 0.5).float()

        def step():
            opt.zero_grad()
            F.binary_cross_entropy_with_logits(net(y), t).backward()
            opt.step()
        return b / timed(step, reps)
    if kind == "score_differences":
        net = ldr(case["ldr"])
        y = torch.randn(code_shape(case["ldr"], b))

        def step():
            yy = y.clone().requires_grad_(True)
            torch.autograd.grad(net(yy).sum(), yy)
        return b / timed(step, reps)
    if kind == "ae2_train":
        spec, lam, n_s = case["ae2"], case["lambda"], case["sparsity_batch"]
        net = Ae2(spec)
        opt = torch.optim.Adam(net.parameters(), lr=1e-3)
        y_r = torch.randn(code_shape(spec, b))
        y_s = torch.randn(code_shape(spec, n_s))
        v = torch.randn(code_shape(spec, n_s))
        v = v / v.flatten(1).norm(dim=1).reshape(-1, 1, 1, 1)
        target = torch.zeros(spec["latent_dim"])
        target[case["target"]] = 1

        def step():
            opt.zero_grad()
            loss = F.mse_loss(net.decode(net.encode(y_r)), y_r)
            if lam > 0:
                z = net.encode(y_s)
                jtv = torch.autograd.grad(net.decode(z), z, v, create_graph=True)[0]
                loss = loss + lam * ((jtv.abs().mean(0) - target) ** 2).sum()
            loss.backward()
            opt.step()
        return (b + (n_s if lam > 0 else 0)) / timed(step, reps)
    if kind == "frame_latency":
        ae1, ae2 = Ae1(case["ae1"]), Ae2(case["ae2"])
        cams, side = case["cameras"], case["ae1"]["image_size"]
        x = torch.rand(cams, 1, side, side)
        with torch.no_grad():
            return 1000 * timed(lambda: ae2.encode(ae1.enc(x).reshape(1, cams, 8, 8)), reps)
    raise ValueError(f"unknown case kind {kind}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("cases")
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    global NATIVE_PADDING, SYMMETRIC_CONVS
    for case in json.load(open(args.cases)):
        higher_is_better = not case["kind"].endswith("latency")
        best = None
        SYMMETRIC_CONVS = 0
        for native in (True, False):
            NATIVE_PADDING = native
            torch.manual_seed(0)
            figure = run(case)
            if best is None or (figure > best[0]) == higher_is_better:
                best = (figure, native)
            if SYMMETRIC_CONVS == 0:
                break  # no convolution whose padding the variant changes
        print(f"{case['name']} {best[0]:.4f}", flush=True)
        if SYMMETRIC_CONVS:
            print(f"{case['name']}:native_padding {int(best[1])}", flush=True)


if __name__ == "__main__":
    main()
