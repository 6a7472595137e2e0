#!/usr/bin/python3
"""Reference values from PyTorch for test/torch_parity_test.cpp.

Uses Debian's python3-torch (1.13, CPU, one thread, float32) and writes
test/fixtures/torch_parity.safetensors with every input, output and gradient, named
"<case>.<tensor>". Regenerate with:
    apt-get install python3-torch
    /usr/bin/python3 src/ropes_nn/test/make_torch_fixtures.py
The C++ test recomputes each case with ropes_nn from the stored inputs.
"""
import os
import sys

import torch
import torch.nn.functional as F

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tools"))
import safetensors_io  # noqa: E402

torch.manual_seed(0)
torch.set_num_threads(1)
out = {}


def leaf(*shape, scale=1.0):
    return (torch.randn(*shape) * scale).requires_grad_(True)


def keep(case, **tensors):
    for name, t in tensors.items():
        out[f"{case}.{name}"] = t.detach().numpy().copy()


def grads_of(loss, **inputs):
    """Gradients of loss; zeros for inputs it does not depend on (b3 of the decoder)."""
    names = list(inputs)
    gs = torch.autograd.grad(loss, [inputs[n] for n in names], allow_unused=True)
    return {f"grad_{n}": torch.zeros_like(inputs[n]) if g is None else g
            for n, g in zip(names, gs)}


# conv2d, stride 2, kernel 4 on 7x7: Flax SAME pads 1 before, 2 after (asymmetric)
x, w, b = leaf(2, 3, 7, 7), leaf(4, 3, 4, 4, scale=0.3), leaf(4)
y = F.conv2d(F.pad(x, (1, 2, 1, 2)), w, b, stride=2)
r = torch.randn_like(y)
keep("conv", x=x, w=w, b=b, y=y, r=r, **grads_of((y * r).sum(), x=x, w=w, b=b))

# conv_transpose2d, kernel 4, stride 2, SAME == PyTorch padding 1
x, w, b = leaf(2, 3, 5, 5), leaf(3, 2, 4, 4, scale=0.3), leaf(2)
y = F.conv_transpose2d(x, w, b, stride=2, padding=1)
r = torch.randn_like(y)
keep("convt", x=x, w=w, b=b, y=y, r=r, **grads_of((y * r).sum(), x=x, w=w, b=b))

# group norm, 2 groups of 2 channels
x, gamma, beta = leaf(2, 4, 3, 3), leaf(4), leaf(4)
y = F.group_norm(x, 2, gamma, beta, eps=1e-5)
r = torch.randn_like(y)
keep("gn", x=x, gamma=gamma, beta=beta, y=y, r=r,
     **grads_of((y * r).sum(), x=x, gamma=gamma, beta=beta))

# dense + BCE with logits, and MSE
x, w, b = leaf(5, 6), leaf(6, 3, scale=0.5), leaf(3)
t = (torch.rand(5, 3) > 0.5).float()
loss = F.binary_cross_entropy_with_logits(x @ w + b, t)
keep("bce", x=x, w=w, b=b, t=t, loss=loss, **grads_of(loss, x=x, w=w, b=b))
a, t = leaf(4, 5), torch.randn(4, 5)
loss = F.mse_loss(a, t)
keep("mse", a=a, t=t, loss=loss, **grads_of(loss, a=a))

# ResBlockGN(4 channels, 2 groups, eps 1e-6): x + conv2(relu(gn2(conv1(relu(gn1(x))))))
p = {"norm1.scale": leaf(4), "norm1.bias": leaf(4), "conv1.weight": leaf(4, 4, 3, 3, scale=0.2),
     "conv1.bias": leaf(4), "norm2.scale": leaf(4), "norm2.bias": leaf(4),
     "conv2.weight": leaf(4, 4, 3, 3, scale=0.2), "conv2.bias": leaf(4)}
x = leaf(2, 4, 6, 6)
h = F.conv2d(F.relu(F.group_norm(x, 2, p["norm1.scale"], p["norm1.bias"], eps=1e-6)),
             p["conv1.weight"], p["conv1.bias"], padding=1)
y = x + F.conv2d(F.relu(F.group_norm(h, 2, p["norm2.scale"], p["norm2.bias"], eps=1e-6)),
                 p["conv2.weight"], p["conv2.bias"], padding=1)
r = torch.randn_like(y)
gs = torch.autograd.grad((y * r).sum(), [x] + list(p.values()))
keep("resblock", x=x, y=y, r=r, grad_x=gs[0])
for (name, t), g in zip(p.items(), gs[1:]):
    out[f"resblock.{name}"] = t.detach().numpy().copy()
    out[f"resblock.grad.{name}"] = g.detach().numpy().copy()

# the score-sparsity loss through a small decoder: double backward of J_g(z)^T v
enc_w, enc_b = leaf(5, 2, scale=0.5), leaf(2, scale=0.1)
w1, b1 = leaf(2, 16, scale=0.5), leaf(16, scale=0.1)
w2, b2 = leaf(4, 2, 4, 4, scale=0.3), leaf(2, scale=0.1)
gamma, beta = leaf(2), leaf(2)
w3, b3 = leaf(1, 2, 3, 3, scale=0.3), leaf(1, scale=0.1)
y_in = torch.randn(3, 5)
v = torch.randn(3, 1, 4, 4)
z = y_in @ enc_w + enc_b                                        # "encoder": [3, 2]


def decoder(z):
    h = F.relu(z @ w1 + b1).reshape(3, 4, 2, 2)
    h = F.conv_transpose2d(h, w2, b2, stride=2, padding=1)      # [3, 2, 4, 4]
    h = F.relu(F.group_norm(h, 1, gamma, beta, eps=1e-6))
    return F.conv2d(h, w3, b3, padding=1)                       # [3, 1, 4, 4]


jtv = torch.autograd.grad(decoder(z), z, v, create_graph=True)[0]  # [3, 2]
target = torch.tensor([0.0, 1.0])
loss = ((jtv.abs().mean(dim=0) - target) ** 2).sum()
params = dict(enc_w=enc_w, enc_b=enc_b, w1=w1, b1=b1, w2=w2, b2=b2, gamma=gamma, beta=beta,
              w3=w3, b3=b3)
keep("sparsity", y_in=y_in, v=v, jtv=jtv, loss=loss, **params, **grads_of(loss, **params))

# Adam: three steps with given gradients, lr 0.01, weight decay 0.1
p0 = torch.randn(3, 4)
param = p0.clone().requires_grad_(True)
opt = torch.optim.Adam([param], lr=0.01, weight_decay=0.1)
grads = [torch.randn(3, 4) for _ in range(3)]
for g in grads:
    param.grad = g.clone()
    opt.step()
keep("adam", p0=p0, g0=grads[0], g1=grads[1], g2=grads[2], p3=param)

path = os.path.join(os.path.dirname(__file__), "fixtures", "torch_parity.safetensors")
safetensors_io.save(path, out, {"generator": "make_torch_fixtures.py",
                                "torch": torch.__version__})
print(f"wrote {len(out)} tensors to {path}")
