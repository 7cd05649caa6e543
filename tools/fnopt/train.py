#!/usr/bin/python3
"""Self-supervised training of the FNOpt learned optimizer with the ask/tell environment pool
(docs/FNOPT.md, "Training"). Resumable: rerun the same command to continue from the last
checkpoint in --out. Only physics losses are used; there is no ground-truth data.

    nice -n 10 /usr/bin/python3 tools/fnopt/train.py --out data/fnopt/run --epochs 20 --batches 250 \
        --export data/fnopt/run/fnopt_32.safetensors

then copy the export to tools/fnopt/models/ and rerun tools/fnopt/make_golden.py.
"""
import argparse
import csv
import json
import math
import os
import sys
import time

import numpy as np
import torch

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fnopt_torch as ft  # noqa: E402


def rot_matrix(yaw, pitch, roll):
    cy, sy = math.cos(yaw), math.sin(yaw)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cr, sr = math.cos(roll), math.sin(roll)
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    return torch.tensor(rz @ ry @ rx, dtype=torch.float32)


class Pool:
    """dataset_size cloth environments that share one iterations-per-timestep value."""

    def __init__(self, size, h, w, ips, rng, seq_len, batch_size, gravity=(0.125, 0.125), speed=(1.0, 1.0)):
        self.n, self.h, self.w, self.ips, self.rng = size, h, w, ips, rng
        # gravity magnitude and handle-speed factor, log-uniform per reset: gravity in grid units grows
        # with resolution and frame rate, handle speeds in grid units grow with resolution
        self.gravity, self.speed = gravity, speed
        self.batch_size = batch_size
        z3 = lambda: torch.zeros(size, 3, h, w)  # noqa: E731
        self.x, self.v, self.a, self.bc, self.bc_orig = z3(), z3(), z3(), z3(), z3()
        self.g_prev, self.s_prev = z3(), z3()
        self.scale = torch.full((size, 3), 0.05)
        self.mask = torch.zeros(size, 1, h, w)
        self.f = torch.zeros(size, 3, 1, 1)
        self.moving = np.zeros(size, bool)
        self.drot = np.zeros((size, 3))
        self.freq = torch.zeros(size, 3, 1, 1)
        self.amp = torch.zeros(size, 3, 1, 1)
        self.pinch = np.zeros(size)
        self.T = np.zeros(size, np.int64)
        self.iters = np.zeros(size, np.int64)
        lu = lambda lo, hi: torch.tensor(np.exp(rng.uniform(math.log(lo), math.log(hi), size)), dtype=torch.float32)  # noqa: E731
        # material drawn once per slot, kept across resets
        self.Y, self.S, self.B = lu(100, 1000), lu(1, 100), lu(0.01, 10)
        self.reset_every = max(1, int(seq_len * ips / batch_size))
        self.tells = 0
        self.next_reset = 0
        for i in range(size):
            self.reset(i)

    def reset(self, i):
        rng, h, w = self.rng, self.h, self.w
        R = rot_matrix(*rng.uniform(-2 * math.pi, 2 * math.pi, 3))
        ii, jj = torch.meshgrid(torch.arange(h, dtype=torch.float32), torch.arange(w, dtype=torch.float32), indexing='ij')
        flat = torch.stack([jj, ii - (h - 1) / 2, torch.zeros_like(ii)], 0)
        x0 = torch.einsum('ab,bhw->ahw', R, flat)
        m = torch.zeros(1, h, w)
        m[0, 0, 0] = 1
        m[0, h - 1, 0] = 1
        while rng.random() < 0.5:
            m[0, rng.integers(h), rng.integers(w)] = 1
        self.x[i] = x0
        self.v[i] = 0
        self.a[i] = 0
        self.mask[i] = m
        self.bc_orig[i] = x0 * m
        self.bc[i] = x0 * m
        G = rot_matrix(*rng.uniform(-2 * math.pi, 2 * math.pi, 3))
        lu = lambda r: float(math.exp(rng.uniform(math.log(r[0]), math.log(r[1]))))  # noqa: E731
        self.f[i] = (G @ torch.tensor([0.0, 0.0, -lu(self.gravity)])).reshape(3, 1, 1)
        self.moving[i] = rng.random() < 0.8
        sp = lu(self.speed)
        self.drot[i] = sp * rng.uniform(-0.0628, 0.0628, 3)
        self.freq[i] = torch.tensor(sp * rng.uniform(-0.2, 0.2, 3), dtype=torch.float32).reshape(3, 1, 1)
        self.amp[i] = torch.tensor(rng.uniform(-10, 10, 3), dtype=torch.float32).reshape(3, 1, 1)
        self.pinch[i] = sp * rng.uniform(-0.2, 0.2)
        self.T[i] = 0
        self.iters[i] = 0
        self.g_prev[i] = 0
        self.s_prev[i] = 0
        self.scale[i] = 0.05

    def update(self, i):
        """Backward-Euler state update of environment i, then move its handles."""
        self.v[i] += self.a[i]
        self.x[i] += self.v[i]
        m = self.mask[i]
        self.x[i] = m * self.bc[i] + (1 - m) * self.x[i]
        self.v[i] = (1 - m) * self.v[i]
        self.a[i] = 0
        self.T[i] += 1
        if self.moving[i]:
            R = rot_matrix(*self.drot[i])
            self.bc_orig[i] = torch.einsum('ab,bhw->ahw', R, self.bc_orig[i]) * m
            t = float(self.T[i])
            self.bc[i] = self.bc_orig[i] * (0.6 + 0.4 * math.cos(t * self.pinch[i])) + \
                torch.sin(t * self.freq[i]) * self.amp[i] * m
        e = ft.internal_energy(self.x[i:i + 1], self.Y[i:i + 1], self.S[i:i + 1], self.B[i:i + 1])
        if not torch.isfinite(e).all() or float(e) > 20000:
            self.reset(i)

    def args(self, idx):
        return (self.x[idx], self.v[idx], None, self.f[idx], self.mask[idx], self.bc[idx],
                self.Y[idx], self.S[idx], self.B[idx])


def train_step(net, pools, rng):
    total = 0.0
    terms = []
    for p in pools:
        idx = torch.tensor(rng.choice(p.n, p.batch_size, replace=False))
        x, v, _, f, m, bc, Y, S, B = p.args(idx)
        g, _ = ft.loss_grad(x, v, p.a[idx], f, m, bc, Y, S, B)
        b = len(idx)
        step, new_scale = ft.optimizer_step(net, ft.to_channels(g), ft.to_channels(p.g_prev[idx]),
                                            ft.to_channels(p.s_prev[idx]), p.scale[idx].reshape(-1, 1),
                                            train=True)
        acc = p.a[idx] + ft.from_channels(step, b)
        L = ft.physics_loss(x, v, acc, f, m, bc, Y, S, B)
        total = total + L.mean()
        terms.append(float(L.mean()))
        p.a[idx] = acc.detach()
        p.g_prev[idx] = g
        p.s_prev[idx] = ft.from_channels(step.detach(), b)
        p.scale[idx] = new_scale.detach().reshape(b, 3)
        p.iters[idx.numpy()] += 1
        for i in idx.tolist():
            if p.iters[i] % p.ips == 0:
                p.update(i)
            elif not torch.isfinite(p.a[i]).all() or float(p.scale[i].max()) > 1e6:
                p.reset(i)
        p.tells += 1
        if p.tells % p.reset_every == 0:
            p.reset(p.next_reset)
            p.next_reset = (p.next_reset + 1) % p.n
    return total, terms


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--out', default='data/fnopt/run')
    ap.add_argument('--res', type=int, default=32)
    ap.add_argument('--dataset-size', type=int, default=20, help='environments per pool')
    ap.add_argument('--batch-size', type=int, default=4, help='environments per pool per step')
    ap.add_argument('--ips', default='1,3,10,30', help='iterations per time step, one pool each')
    ap.add_argument('--extra-pools', default='', help='more pools as res:ips:batch, comma separated '
                    '(e.g. 64:10:2 adds a 64 x 64 pool at 10 iterations drawing 2 environments per step)')
    ap.add_argument('--gravity', default='0.125', help='gravity magnitude in grid units/step^2, or lo:hi '
                    'drawn log-uniform at every reset')
    ap.add_argument('--speed', default='1', help='handle-motion speed factor, or lo:hi drawn log-uniform at every reset')
    ap.add_argument('--epochs', type=int, default=20)
    ap.add_argument('--batches', type=int, default=250, help='optimizer steps per epoch')
    ap.add_argument('--seq-len', type=int, default=1000, help='average time steps per environment')
    ap.add_argument('--lr', type=float, default=1e-3)
    ap.add_argument('--threads', type=int, default=1)
    ap.add_argument('--seed', type=int, default=1)
    ap.add_argument('--stop-at', default='', help='UTC HH:MM: checkpoint and exit at this time')
    ap.add_argument('--max-seconds', type=float, default=0, help='checkpoint and exit this many seconds after '
                    'the start (0: no limit); for machine windows of a fixed length')
    ap.add_argument('--export', default='', help='write safetensors here after every epoch')
    ap.add_argument('--init-from', default='', help='start from these exported weights (e.g. the shipped '
                    'tools/fnopt/models/fnopt_32.safetensors) when --out has no checkpoint yet')
    args = ap.parse_args()
    t_start = time.time()
    torch.set_num_threads(args.threads)
    os.makedirs(args.out, exist_ok=True)
    ckpt_path = os.path.join(args.out, 'checkpoint.pt')
    log_path = os.path.join(args.out, 'loss_log.csv')
    ips_list = [int(s) for s in args.ips.split(',')]
    specs = [(args.res, ips, args.batch_size) for ips in ips_list]
    for e in filter(None, args.extra_pools.split(',')):
        r, i, b = (int(t) for t in e.split(':'))
        specs.append((r, i, b))

    def rng_pair(text):
        v = [float(t) for t in text.split(':')]
        return (v[0], v[-1])
    gravity, speed = rng_pair(args.gravity), rng_pair(args.speed)

    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)
    net = ft.FNO()
    init_batches = 0
    if args.init_from and not os.path.exists(ckpt_path):
        net, init_meta = ft.import_model(args.init_from)
        init_batches = int(init_meta.get('batches_done', 0)) + int(init_meta.get('init_batches', 0))
        print(f'starting from the weights in {args.init_from} (fresh optimizer and pool)')
    opt = torch.optim.AdamW(net.parameters(), lr=args.lr)
    ms = [args.epochs // 4, args.epochs // 2, 3 * args.epochs // 4]
    sched = torch.optim.lr_scheduler.MultiStepLR(opt, milestones=ms, gamma=0.5)
    pools = [Pool(args.dataset_size, r, r, ips, rng, args.seq_len, b, gravity, speed) for r, ips, b in specs]
    epoch, batch = 0, 0
    if os.path.exists(ckpt_path):
        st = torch.load(ckpt_path)
        net.load_state_dict(st['model'])
        opt.load_state_dict(st['optimizer'])
        sched.load_state_dict(st['scheduler'])
        pools = st['pools']
        init_batches = st.get('init_batches', 0)
        for p in pools:  # checkpoints written before the gravity/speed ranges existed
            if not hasattr(p, 'batch_size'):
                p.batch_size, p.speed = args.batch_size, (1.0, 1.0)
                p.gravity = (p.gravity, p.gravity)
        rng = st['rng']
        for p in pools:
            p.rng = rng
        torch.set_rng_state(st['torch_rng'])
        epoch, batch = st['epoch'], st['batch']
        print(f'resumed from {ckpt_path}: epoch {epoch} batch {batch}')

    def save():
        tmp = ckpt_path + '.tmp'
        torch.save(dict(model=net.state_dict(), optimizer=opt.state_dict(), scheduler=sched.state_dict(),
                        pools=pools, rng=rng, torch_rng=torch.get_rng_state(), epoch=epoch, batch=batch,
                        init_batches=init_batches, args=vars(args)), tmp)
        os.replace(tmp, ckpt_path)
        if args.export:
            ft.export_model(net, args.export, extra=dict(
                train_res=args.res, epochs_done=epoch, batches_done=epoch * args.batches + batch,
                init_batches=init_batches, pools=' '.join(f'{r}:{i}:{b}' for r, i, b in specs),
                gravity=args.gravity, speed=args.speed))

    new_log = not os.path.exists(log_path)
    logf = open(log_path, 'a', newline='')
    log = csv.writer(logf)
    if new_log:
        names = [f'loss_ips{i}' if r == args.res else f'loss_r{r}_ips{i}' for r, i, _ in specs]
        log.writerow(['epoch', 'batch', 'loss'] + names + ['lr', 'seconds'])
    t0 = time.time()
    last_save = time.time()
    while epoch < args.epochs:
        while batch < args.batches:
            total, terms = train_step(net, pools, rng)
            opt.zero_grad()
            total.backward()
            torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
            opt.step()
            batch += 1
            log.writerow([epoch, batch, f'{float(total):.6g}'] + [f'{t:.6g}' for t in terms] +
                         [f'{opt.param_groups[0]["lr"]:.3g}', f'{time.time() - t0:.1f}'])
            done = batch / args.batches
            bar = '#' * int(30 * done) + '-' * (30 - int(30 * done))
            sys.stdout.write(f'\repoch {epoch + 1}/{args.epochs} [{bar}] {batch}/{args.batches} '
                             f'loss {float(total):.4g} ({time.time() - t0:.0f}s)')
            sys.stdout.flush()
            if time.time() - last_save > 300:
                logf.flush()
                save()
                last_save = time.time()
            if (args.stop_at and time.strftime('%H:%M', time.gmtime()) >= args.stop_at) or \
                    (args.max_seconds > 0 and time.time() - t_start >= args.max_seconds):
                logf.flush()
                save()
                print(f'\nstopped (epoch {epoch} batch {batch}, {time.time() - t_start:.0f} s); rerun to resume')
                return
        epoch += 1
        batch = 0
        sched.step()
        logf.flush()
        save()
        sys.stdout.write('\n')
    print('training finished')


if __name__ == '__main__':
    main()
