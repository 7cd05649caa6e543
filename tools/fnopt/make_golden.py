#!/usr/bin/python3
"""Golden tensors for the C parity tests (tests/fnopt/data/), computed in float64 PyTorch.

    /usr/bin/python3 tools/fnopt/make_golden.py --model tools/fnopt/models/fnopt_32.safetensors

Writes tests/fnopt/data/loss_golden.safetensors (loss and gradient, with and without repulsion)
and tests/fnopt/data/rollout_golden.safetensors (the learned optimizer's acceleration after every
inner iteration of two steps on a 20x24 grid, and positions over a 6-step 16x16 rollout).
Arrays are in the C layout: vertex-major xyz, vertex index i*W + j.
"""
import argparse
import os
import sys

import numpy as np
import torch

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fnopt_torch as ft  # noqa: E402

D = torch.float64


def hanging(h, w):
    ii, jj = torch.meshgrid(torch.arange(h, dtype=D), torch.arange(w, dtype=D), indexing='ij')
    return torch.stack([ii - (h - 1) / 2, torch.zeros_like(ii), -jj], 0)[None]


def arr(t):
    return torch.as_tensor(t, dtype=torch.float32)


def loss_case(out, prefix, h, w, squeeze, k_rep, gen):
    x = hanging(h, w) * squeeze + 0.3 * torch.randn(1, 3, h, w, generator=gen, dtype=D)
    v = 0.05 * torch.randn(1, 3, h, w, generator=gen, dtype=D)
    acc = 0.1 * torch.randn(1, 3, h, w, generator=gen, dtype=D)
    mask = torch.zeros(1, 1, h, w, dtype=D)
    handles = [0, w - 1, 3 * w + 4]
    for k in handles:
        mask[0, 0, k // w, k % w] = 1
    bc = mask * (x + 0.2 * torch.randn(1, 3, h, w, generator=gen, dtype=D))
    Y, S, B = torch.tensor([500.0], dtype=D), torch.tensor([20.0], dtype=D), torch.tensor([2.0], dtype=D)
    f = torch.tensor([0.01, -0.02, -0.12], dtype=D).reshape(1, 3, 1, 1)
    g, L = ft.loss_grad(x, v, acc, f, mask, bc, Y, S, B, k_rep)
    out[prefix + 'x'] = arr(ft.grid_to_c(x))
    out[prefix + 'v'] = arr(ft.grid_to_c(v))
    out[prefix + 'acc'] = arr(ft.grid_to_c(acc))
    out[prefix + 'bc'] = arr(ft.grid_to_c(bc))
    out[prefix + 'handles'] = torch.tensor(handles, dtype=torch.float32)
    out[prefix + 'params'] = torch.tensor([h, w, 500.0, 20.0, 2.0, 0.01, -0.02, -0.12, k_rep], dtype=torch.float32)
    out[prefix + 'loss'] = torch.tensor([float(L)], dtype=torch.float32)
    out[prefix + 'grad'] = arr(ft.grid_to_c(g))
    # float64 reference is computed from the float32-rounded inputs the C side reads
    return L


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--model', default='tools/fnopt/models/fnopt_32.safetensors')
    ap.add_argument('--out', default='tests/fnopt/data')
    args = ap.parse_args()
    torch.set_num_threads(1)
    os.makedirs(args.out, exist_ok=True)
    gen = torch.Generator().manual_seed(7)

    # inputs are rounded to float32 first so that C and PyTorch see the same numbers
    out = {}
    for prefix, h, w, sq, k in [('plain.', 12, 14, 1.0, 0.0), ('rep.', 12, 14, 0.25, 0.01)]:
        loss_case(out, prefix, h, w, sq, k, gen)
    # recompute from the rounded inputs
    for prefix in ('plain.', 'rep.'):
        p = out[prefix + 'params'].tolist()
        h, w = int(p[0]), int(p[1])
        g2c = lambda name: ft.c_to_grid(out[prefix + name].numpy(), h, w).to(D)  # noqa: E731
        mask = torch.zeros(1, 1, h, w, dtype=D)
        for k in out[prefix + 'handles'].tolist():
            mask[0, 0, int(k) // w, int(k) % w] = 1
        f = torch.tensor(p[5:8], dtype=D).reshape(1, 3, 1, 1)
        g, L = ft.loss_grad(g2c('x'), g2c('v'), g2c('acc'), f, mask, mask * g2c('bc'),
                            torch.tensor([p[2]], dtype=D), torch.tensor([p[3]], dtype=D),
                            torch.tensor([p[4]], dtype=D), p[8])
        out[prefix + 'loss'] = torch.tensor([float(L)], dtype=torch.float32)
        out[prefix + 'grad'] = arr(ft.grid_to_c(g))
        print(f'{prefix} loss {float(L):.9g}')
    ft.save_safetensors(os.path.join(args.out, 'loss_golden.safetensors'), out, {"name": "fnopt loss golden"})

    net, cfg = ft.import_model(args.model)
    net = net.to(D)
    rout = {}
    # per-iteration parity on a non-square grid with two moving corner handles
    h, w = 20, 24
    x0 = (hanging(h, w) + 0.05 * torch.randn(1, 3, h, w, generator=gen, dtype=D)).float().to(D)
    mask = torch.zeros(1, 1, h, w, dtype=D)
    hid = [0, (h - 1) * w]
    for k in hid:
        mask[0, 0, k // w, k % w] = 1
    grav = [0.0, 0.0, -0.12]
    ro = ft.Rollout(net, x0, 1000.0, 8.0, 0.5, grav, mask, scale0=cfg['initial_scale'])
    rout['iter.x0'] = arr(ft.grid_to_c(x0))
    rout['iter.params'] = torch.tensor([h, w, 1000.0, 8.0, 0.5] + grav + hid, dtype=torch.float32)
    for s in range(2):
        bc = mask * (x0 + torch.tensor([0.3 * (s + 1), 0.2 * (s + 1), 0.1], dtype=D).reshape(1, 3, 1, 1))
        bc = bc.float().to(D)
        trace = []
        ro.step(bc, 10, trace)
        rout[f'iter.bc{s}'] = arr(ft.grid_to_c(bc))
        rout[f'iter.acc{s}'] = torch.stack([arr(ft.grid_to_c(a)) for a in trace])
        rout[f'iter.xs{s}'] = arr(ft.grid_to_c(ro.x))
    # 6-step rollout on a 16x16 sheet, handles translating along +x+z. The sheet starts slightly
    # crumpled: on an exactly flat sheet many bend angles sit at the acos clamp, where the
    # reference gradient jumps, and float rounding alone decides which side they fall on.
    h = w = 16
    x0 = (hanging(h, w) + 0.05 * torch.randn(1, 3, h, w, generator=gen, dtype=D)).float().to(D)
    mask = torch.zeros(1, 1, h, w, dtype=D)
    hid = [0, (h - 1) * w]
    for k in hid:
        mask[0, 0, k // w, k % w] = 1
    grav = [0.0, 0.0, -0.121]
    ro = ft.Rollout(net, x0, 1000.0, 8.0, 0.5, grav, mask, scale0=cfg['initial_scale'])
    rout['roll.x0'] = arr(ft.grid_to_c(x0))
    rout['roll.params'] = torch.tensor([h, w, 1000.0, 8.0, 0.5] + grav + hid, dtype=torch.float32)
    xs = []
    for s in range(6):
        bc = (mask * (x0 + torch.tensor([0.25 * (s + 1), 0.0, 0.25 * (s + 1)], dtype=D).reshape(1, 3, 1, 1))).float().to(D)
        ro.step(bc, 10)
        xs.append(arr(ft.grid_to_c(ro.x)))
    rout['roll.x'] = torch.stack(xs)
    ft.save_safetensors(os.path.join(args.out, 'rollout_golden.safetensors'), rout,
                        {"name": "fnopt rollout golden", "model": os.path.basename(args.model)})
    print('rollout final mean z', float(xs[-1][:, 2].mean()))


if __name__ == '__main__':
    main()
