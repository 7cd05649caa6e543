"""Train the ClothTransformer on simgen sequences.

Resumable: checkpoints go to OUT/ckpt.pt every --ckpt-every steps and when --max-minutes is reached;
rerun the same command with --resume to continue. Losses are appended to OUT/log.csv.

  /usr/bin/python3 tools/train/train.py --data data/simgen --preset game --out tools/train/runs/game \
      --steps 4000 --max-minutes 30 --resume
  torchrun --nproc_per_node 2 tools/train/train.py ...       # DDP (gloo), one process per core/GPU

Stages: `--stage pretrain` (MSE + cubic contact penalty, rollout curriculum 1 -> --rollout-max),
`--stage ccd` adds the differentiable CCD loss (needs tools/train/weft_ccd.py and libweft).
"""
import argparse
import csv
import json
import math
import os
import random
import sys
import time

# OpenBLAS (Debian's torch) keeps its own thread pool, sized to the machine, not to --threads;
# beside other busy processes its idle threads spin in sched_yield (measured on 2 cores beside
# two simgen shards: 100 % system time, 50 steps in 3.4 minutes). Size it before numpy loads it.
_threads_arg = [sys.argv[i + 1] for i, v in enumerate(sys.argv[:-1]) if v == "--threads"]
os.environ.setdefault("OPENBLAS_NUM_THREADS", _threads_arg[-1] if _threads_arg else "1")

import numpy as np  # noqa: E402
import torch  # noqa: E402
import torch.distributed as dist  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import data as weft_data  # noqa: E402
from model import ClothTransformer, attach, full_config, mean_adjacency, prior_positions  # noqa: E402

PRESETS = {
    # small and fast: the in-game model
    "game": {"K": 32, "D": 48, "L": 2, "H": 4, "history": 1, "ffn": 96, "nfreq": 6},
    # tiny model for C parity tests (exercises history > 1 and every code path)
    "golden": {"K": 16, "D": 32, "L": 2, "H": 2, "history": 2, "ffn": 64, "nfreq": 4},
}


class MeshCache:
    """Per-sequence tensors that do not change over time (adjacency, rest shape, triangles)."""

    def __init__(self, device):
        self.device = device
        self.cache = {}

    def get(self, seq):
        c = self.cache.get(seq.folder)
        if c is None:
            f = np.asarray(seq.faces, dtype=np.int64)
            e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
            e = np.unique(np.sort(e, axis=1), axis=0)
            rest_len = np.linalg.norm(seq.rest[e[:, 0]] - seq.rest[e[:, 1]], axis=1)
            c = {
                "adj": mean_adjacency(seq.faces, seq.rest.shape[0]).to(self.device),
                "edges": torch.from_numpy(e).to(self.device),
                "rest_len": torch.from_numpy(np.maximum(rest_len, 1e-6).astype(np.float32)).to(self.device),
                "rest": torch.from_numpy(seq.rest).to(self.device).unsqueeze(0),
                "ctri": None if seq.cfaces is None else torch.from_numpy(seq.cfaces).to(self.device),
            }
            self.cache[seq.folder] = c
        return c


def data_stats(seqs, cfg):
    """Scales that bring inputs and outputs to unit order (stored in the model config)."""
    prior = cfg["prior"]
    vel, res, area = [], [], []
    for s in seqs[:64]:
        x = np.asarray(s.pos, dtype=np.float64)
        v = x[1:] - x[:-1]
        vel.append(v.reshape(-1))
        if prior == "skinned" and s.skin is None:   # refused after the config is settled (main)
            continue
        # the prior of every frame t+1 from (X_t, X_{t-1}): model.py's own, in float64; the grasp
        # prior with its pins at t+1 (the reference's positions), attached as a step's output is
        xt, xp = torch.from_numpy(x[1:-1]), torch.from_numpy(x[:-2])
        sk = None if s.skin is None else torch.from_numpy(np.asarray(s.skin, dtype=np.float64))
        pm = None if prior != "grasp" or s.pinned is None else torch.from_numpy(np.asarray(s.pinned[2:]) != 0)
        rest = torch.from_numpy(np.asarray(s.rest, dtype=np.float64)).unsqueeze(0)
        pt = prior_positions(cfg, xt, xp, None if sk is None else sk[2:], None if sk is None else sk[1:-1],
                             pm, torch.from_numpy(x[2:]), rest)
        if prior == "grasp" and cfg["attach_output"]:
            pt = attach(pt, pm, torch.from_numpy(x[2:]), rest)
        p = pt.numpy()
        res.append((x[2:] - p).reshape(-1))
        if s.cfaces is not None:
            c = np.asarray(s.cpos[0], dtype=np.float64)
            t = c[s.cfaces]
            cr = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
            area.append(np.sqrt(0.5 * np.linalg.norm(cr, axis=1)))
    vs = float(np.sqrt(np.mean(np.concatenate(vel) ** 2)) + 1e-6)
    rs = float(np.sqrt(np.mean(np.concatenate(res) ** 2)) + 1e-6)
    a = float(np.mean(np.concatenate(area))) if area else 0.01
    return {"vel_scale": round(1.0 / vs, 4), "out_scale": float(f"{rs:.4g}"), "area_scale": round(1.0 / a, 4)}


def contact_penalty(x, c_next, ctri, max_depth=0.05):
    """Cubic penalty (cm^3) on penetration along the normal of the nearest collider triangle."""
    if ctri is None:
        return x.new_zeros(())
    p = c_next[:, ctri, :]                                   # (B, M, 3, 3)
    cen = p.mean(dim=2)
    n = torch.cross(p[:, :, 1] - p[:, :, 0], p[:, :, 2] - p[:, :, 0], dim=-1)
    n = n / (n.norm(dim=-1, keepdim=True) + 1e-12)
    idx = torch.cdist(x, cen).argmin(dim=-1)                 # (B, N)
    g = lambda t: torch.gather(t, 1, idx.unsqueeze(-1).expand(-1, -1, 3))  # noqa: E731
    s = ((x - g(cen)) * g(n)).sum(-1)
    d = torch.clamp(s, max=0.0) * (s > -max_depth)
    return (d.abs() * 100.0).pow(3).mean()


def strain_penalty(x, edges, rest_len):
    """Mean squared edge strain (|e| / |e0| - 1)^2 of predicted positions (B, V, 3)."""
    d = x[:, edges[:, 0]] - x[:, edges[:, 1]]
    return ((d.norm(dim=-1) / rest_len - 1.0) ** 2).mean()


class Rollout(torch.nn.Module):
    """The whole autoregressive rollout as one forward() (DDP needs one forward per backward).

    x_all/c_all/s_all: (B, T, V, 3) windows (s_all: the S track, skinned prior). With prefill, the latent history is first filled from
    ground-truth frames; without, it starts empty (the state after weft_garment_set_state).
    p_all: (B, T, V) bool pin masks, or None: pinned vertices of each predicted frame take their
    ground-truth positions before the next step, as weft_garment_set_pins does after a learned step.
    Returns the predictions (B, steps, V, 3) of frames base+2 .. base+1+steps."""

    def __init__(self, m):
        super().__init__()
        self.m = m
        self.cfg = m.cfg

    def forward(self, x_all, c_all, rest, adj, ctri, steps: int, prefill: bool, s_all=None, p_all=None):
        m = self.m
        base = self.cfg["history"] - 1 if prefill else 0
        hist = []
        with torch.no_grad():
            for k in range(1, base + 1):
                cn = None if c_all is None else c_all[:, k + 1]
                cc = None if c_all is None else c_all[:, k]
                z, _ = m.encode(x_all[:, k], x_all[:, k - 1], adj, cn, cc, ctri)
                hist.append(z)
        xp, x = x_all[:, base], x_all[:, base + 1]
        preds = []
        for r in range(steps):
            t = base + 1 + r
            cn = None if c_all is None else c_all[:, t + 1]
            cc = None if c_all is None else c_all[:, t]
            sn = None if s_all is None else s_all[:, t + 1]
            sc = None if s_all is None else s_all[:, t]
            pm = None if p_all is None else p_all[:, t + 1]
            xn, hist = m.step(hist, x, xp, rest, adj, cn, cc, ctri, sn, sc, pm, x_all[:, t + 1])
            if p_all is not None:
                xn = torch.where(p_all[:, t + 1].unsqueeze(-1), x_all[:, t + 1], xn)
            preds.append(xn)
            xp, x = x, xn
        return torch.stack(preds, dim=1)


def rollout_base(cfg, prefill):
    return cfg["history"] - 1 if prefill else 0


def evaluate(model, seqs, mc, device, frames=60, pins=False):
    """Mean vertex error (cm) of an autoregressive rollout from the first two GT frames (with pins:
    the sequence's pinned vertices follow the reference, as `weft eval --pins all`)."""
    ro = Rollout(model)
    errs = []
    for s in seqs:
        T = min(s.frames, frames + 2)
        x, c = s.window(0, T)
        sk = s.skin_window(0, T)
        xa = torch.from_numpy(x).to(device).unsqueeze(0)
        ca = None if c is None else torch.from_numpy(c).to(device).unsqueeze(0)
        sa = None if sk is None else torch.from_numpy(sk).to(device).unsqueeze(0)
        pm = s.pin_window(0, T) if pins else None
        pa = None if pm is None else torch.from_numpy(pm).to(device).unsqueeze(0)
        mesh = mc.get(s)
        with torch.no_grad():
            preds = ro(xa, ca, mesh["rest"], mesh["adj"], mesh["ctri"], T - 2, False, sa, pa)
        errs.append(float((preds - xa[:, 2:T]).norm(dim=-1).mean()) * 100.0)
    return float(np.mean(errs)) if errs else float("nan")


def ccd_loss(world, x0, x1, out_scale, eps=0.05):
    """ClothTransformer Eq. 3 on self vertex-face / edge-edge hits found by weft's CCD while the
    cloth moves x0 -> x1 (detect, then regress x1 toward the safe positions; in out_scale units)."""
    import weft_ccd
    total = x1.new_zeros(())
    for b in range(x1.shape[0]):
        a0 = x0[b].detach().cpu().numpy()
        a1 = x1[b].detach().cpu().numpy()
        hits = world.detect(a0, a1, types="self")
        if len(hits["toi"]) == 0:
            continue
        safe = torch.from_numpy(weft_ccd.safe_positions(a0, a1, hits["vertices"], hits["toi"], eps)).to(x1)
        v = torch.from_numpy(hits["vertices"]).to(x1.device)
        d = (x1[b][v] - safe) / out_scale                       # (K, 4, 3)
        total = total + (d * d).sum(-1).mean(-1).mean()
    return total / x1.shape[0]


def save_ckpt(path, state):
    tmp = path + ".tmp"
    torch.save(state, tmp)
    os.replace(tmp, path)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", nargs="+", required=True, help="folders searched for sequences")
    ap.add_argument("--preset", choices=sorted(PRESETS), default="game")
    ap.add_argument("--config", default="{}", help="JSON overriding preset entries")
    ap.add_argument("--name", default=None)
    ap.add_argument("--skin", nargs="*", default=[],
                    help="folders of S tracks (<name>.npy, `weft eval --method lbs --write-pos`) for the "
                         "skinned prior, for sequences that do not carry one (packs made with --skin do)")
    ap.add_argument("--out", required=True)
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--batch", type=int, default=4, help="windows per step (same sequence)")
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--rollout-max", type=int, default=5)
    ap.add_argument("--rollout-min", type=int, default=1,
                    help="shortest rollout of the curriculum (a fine-tune of a model already trained "
                         "on long rollouts need not start again at 1)")
    ap.add_argument("--lambda-contact", type=float, default=0.05)
    ap.add_argument("--lambda-ccd", type=float, default=1.0)
    ap.add_argument("--lambda-strain", type=float, default=0.0,
                    help="weight of the mean squared edge strain of the predictions")
    ap.add_argument("--noise-std", type=float, default=0.0,
                    help="Gaussian noise (m) added to the ground-truth input frames of each window, so "
                         "the model learns to correct states off the data manifold (rollout drift)")
    ap.add_argument("--pins", action="store_true",
                    help="pinned vertices (pinned.npy: gripper grasps, waistbands) take their reference "
                         "positions after every predicted step, in training rollouts and validation, as "
                         "the runtime does with weft_garment_set_pins (evaluate with weft eval --pins all)")
    ap.add_argument("--scenario-weight", nargs="*", default=[], metavar="SCENARIO=W",
                    help="draw training sequences of a scenario W times as often (default 1 each)")
    ap.add_argument("--mocap-weight", type=float, default=1.0, metavar="W",
                    help="draw real-motion training sequences (meta.json with a mocap block: weft simgen "
                         "--mocap) W times as often as procedural ones (default 1)")
    ap.add_argument("--scenarios", default="",
                    help="comma-separated scenarios (drop,gripper,garment) to train and validate on "
                         "(default: all): a model for the scenes that need it, e.g. a drop specialist")
    ap.add_argument("--max-train-vertices", type=int, default=0,
                    help="leave training sequences with more cloth vertices out (0: keep all); "
                         "bounds memory at a given batch and rollout length")
    ap.add_argument("--stage", choices=["pretrain", "ccd"], default="pretrain")
    ap.add_argument("--max-minutes", type=float, default=0.0, help="stop (with a checkpoint) after this")
    ap.add_argument("--budget-minutes", type=float, default=0.0,
                    help="schedule (lr decay, rollout curriculum) by training time instead of steps: "
                         "the run ends after this many minutes in all, resumes included")
    ap.add_argument("--ckpt-every", type=int, default=200)
    ap.add_argument("--eval-every", type=int, default=500)
    ap.add_argument("--snapshot-every", type=int, default=0,
                    help="also keep the weights of every Nth step as snap_STEP.pt (weights and config only), "
                         "to choose among them afterwards on a larger validation set than the run sees")
    ap.add_argument("--eval-frames", type=int, default=60)
    ap.add_argument("--keep-best", action="store_true",
                    help="also keep OUT/best.pt: the weights with the lowest validation MVE so far (use a "
                         "long --eval-frames: short rollouts do not show which weights stay stable)")
    ap.add_argument("--resume", action="store_true")
    ap.add_argument("--eval-first", action="store_true",
                    help="validate before the first step (the starting point of a resumed run: with --keep-best "
                         "the weights it starts from are the bar)")
    ap.add_argument("--init-from", default=None,
                    help="start from this checkpoint's weights and config (fine-tuning: fresh optimiser, "
                         "step 0, new schedule); ignored when --resume finds OUT/ckpt.pt")
    ap.add_argument("--init-head-scale", type=float, default=1.0,
                    help="with --init-from, multiply the output head (dec_head) by this: 0 starts the "
                         "fine-tune exactly at its prior (the skinned prior: at LBS), as a fresh model does")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--cuda", action="store_true", help="use a CUDA GPU when present")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()

    ddp = int(os.environ.get("WORLD_SIZE", "1")) > 1
    rank = 0
    if ddp:
        dist.init_process_group("gloo")
        rank = dist.get_rank()
    torch.set_num_threads(a.threads)
    device = torch.device("cuda" if a.cuda and torch.cuda.is_available() else "cpu")
    os.makedirs(a.out, exist_ok=True)
    ckpt_path = os.path.join(a.out, "ckpt.pt")

    train = weft_data.load_sequences(a.data, "train", skin_roots=a.skin)
    val = (weft_data.load_sequences(a.data, "val", skin_roots=a.skin)
           or weft_data.load_sequences(a.data, "test", skin_roots=a.skin))
    if a.scenarios:
        keep = set(a.scenarios.split(","))
        train = [s for s in train if s.scenario in keep]
        val = [s for s in val if s.scenario in keep]
    if a.max_train_vertices > 0:
        train = [s for s in train if s.rest.shape[0] <= a.max_train_vertices]
    if not train:
        sys.exit(f"no training sequences under {a.data}")
    weights = {}
    for sw in a.scenario_weight:
        name, _, w = sw.partition("=")
        try:
            weights[name] = float(w)
        except ValueError:
            sys.exit(f"--scenario-weight {sw}: expected SCENARIO=W")
        if weights[name] < 0:
            sys.exit(f"--scenario-weight {sw}: the weight must be >= 0")
    if not a.mocap_weight >= 0:
        sys.exit(f"--mocap-weight {a.mocap_weight}: the weight must be >= 0")
    draw_w = [weights.get(s.scenario, 1.0) * (a.mocap_weight if "mocap" in s.meta else 1.0) for s in train]
    weighted = bool(weights) or a.mocap_weight != 1.0
    if sum(draw_w) <= 0:
        sys.exit("--scenario-weight leaves no training sequence to draw")
    if a.pins and not any(s.pinned is not None for s in train):
        print("--pins: no training sequence carries pins (pinned.npy, or a pack made since pins were packed)",
              file=sys.stderr)

    state = None
    init = None
    if a.init_from and not (a.resume and os.path.exists(ckpt_path)):
        try:
            init = torch.load(a.init_from, map_location="cpu", weights_only=False)
        except TypeError:
            init = torch.load(a.init_from, map_location="cpu")
    if init is not None:
        cfg = dict(init["config"])
        cfg.update(json.loads(a.config))
    elif a.resume and os.path.exists(ckpt_path):
        try:  # torch >= 2.6 defaults to weights_only loading; our checkpoints hold RNG states
            state = torch.load(ckpt_path, map_location="cpu", weights_only=False)
        except TypeError:
            state = torch.load(ckpt_path, map_location="cpu")
        cfg = state["config"]
    else:
        cfg = dict(PRESETS[a.preset])
        cfg.update(json.loads(a.config))
        cfg.update(data_stats(train, full_config(cfg)))
        # trained only with colliders: the runtime refuses a garment without one
        cfg["requires_collider"] = all(s.cfaces is not None for s in train)
        cfg.update(json.loads(a.config))   # explicit overrides win over measured scales
    cfg = full_config(cfg)
    if cfg["prior"] == "skinned":
        missing = [s.name for s in train + val if s.skin is None]
        if missing:
            sys.exit(f"prior 'skinned' needs the S track; none for {len(missing)} sequence(s) "
                     f"({', '.join(missing[:4])}): pass --skin DIR or pack with --skin")
    random.seed(a.seed + rank)
    torch.manual_seed(a.seed)              # identical initial weights on every rank
    net = ClothTransformer(cfg).to(device)
    opt = torch.optim.AdamW(net.parameters(), lr=a.lr, weight_decay=0.01)
    step = 0
    elapsed_before = 0.0
    if init is not None:
        net.load_state_dict(init["model"])
        if a.init_head_scale != 1.0:
            with torch.no_grad():
                net.dec_head.weight.mul_(a.init_head_scale)
                net.dec_head.bias.mul_(a.init_head_scale)
    if state is not None:
        net.load_state_dict(state["model"])
        step = state["step"]
        elapsed_before = state.get("elapsed", 0.0)
        if "opt" in state:  # slim checkpoints (tools/train/models/*.ckpt.pt) carry weights only
            opt.load_state_dict(state["opt"])
            random.setstate(state["py_rng"])
            torch.set_rng_state(state["torch_rng"])
    model = Rollout(net)
    if ddp:
        # freqs is a constant buffer: nothing to broadcast; collider weights go unused on
        # sequences without a collider
        model = torch.nn.parallel.DistributedDataParallel(model, find_unused_parameters=True,
                                                          broadcast_buffers=False)
    mc = MeshCache(device)
    ccd = None
    ccd_worlds = {}
    if a.stage == "ccd":
        try:
            import weft_ccd  # noqa: F401
            ccd = weft_ccd
        except Exception as e:  # the CCD module is optional: say so and stop
            sys.exit(f"--stage ccd needs tools/train/weft_ccd.py and libweft: {e}")

    log_path = os.path.join(a.out, "log.csv")
    new_log = not os.path.exists(log_path) or state is None
    logf = open(log_path, "w" if new_log else "a", newline="") if rank == 0 else None
    log = csv.writer(logf) if logf else None
    if log and new_log:
        log.writerow(["step", "loss", "mse_cm", "contact", "ccd", "rollout", "lr", "elapsed_s", "val_mve_cm", "strain"])
    if rank == 0:
        with open(os.path.join(a.out, "config.json"), "w") as f:
            json.dump({"config": cfg, "args": vars(a), "train_sequences": len(train)}, f, indent=1)

    t_start = time.time()
    warm = 100
    tty = sys.stderr.isatty()
    out_scale = cfg["out_scale"]
    run_avg = None
    best_val = float("inf")
    best_path = os.path.join(a.out, "best.pt")
    if a.keep_best and os.path.exists(best_path):   # resumed: the best so far stays the bar
        best_val = torch.load(best_path, map_location="cpu").get("val_mve_cm", best_val)
    # A run stopped by the clock still ends with a step and, with validation on, a final
    # validation: the longest of each seen so far is kept back, so the run ends by its limit.
    step_s = eval_s = 0.0

    def timed_eval():
        nonlocal eval_s
        t = time.time()
        v = evaluate(net, val, mc, device, a.eval_frames, a.pins)
        eval_s = max(eval_s, time.time() - t)
        return v

    def reserve_s():
        return step_s + (eval_s if val and (a.eval_every > 0 or a.budget_minutes > 0) else 0.0)

    if rank == 0 and a.eval_first and val:
        v = timed_eval()
        print(f"start val MVE {v:.4f} cm at step {step}", file=sys.stderr, flush=True)
        if log:
            log.writerow([step, "", "", "", "", "", "", f"{elapsed_before:.1f}", f"{v:.4f}", ""])
        if a.keep_best and v < best_val:
            best_val = v
            save_ckpt(best_path, {"model": net.state_dict(), "config": cfg, "step": step, "elapsed": elapsed_before,
                                  "val_mve_cm": v})
    while step < a.steps:
        t_step = time.time()
        if a.budget_minutes > 0:
            progress = (elapsed_before + time.time() - t_start) / (60.0 * a.budget_minutes)
            stop = (elapsed_before + time.time() - t_start + reserve_s()) >= 60.0 * a.budget_minutes
            progress = 1.0 if stop else progress
            if ddp:  # every rank follows rank 0's clock, so all stop at the same step
                pt = torch.tensor([progress], dtype=torch.float64)
                dist.broadcast(pt, 0)
                progress = float(pt.item())
            if progress >= 1.0:
                break
        else:
            progress = step / a.steps
        lr = a.lr * min(1.0, (step + 1) / warm) * (0.1 + 0.9 * 0.5 * (1 + math.cos(math.pi * progress)))
        for gparam in opt.param_groups:
            gparam["lr"] = lr
        R = 1 + min(a.rollout_max - 1, int(a.rollout_max * progress / 0.7))
        R = max(R, min(a.rollout_min, a.rollout_max))
        seq = random.choices(train, draw_w)[0] if weighted else random.choice(train)
        h = cfg["history"]
        need = (h - 1) + R + 2
        if seq.frames < need:
            continue
        starts = [random.randrange(0, seq.frames - need + 1) for _ in range(a.batch)]
        xs, cs = zip(*[seq.window(s0, need) for s0 in starts])
        sa = None
        if cfg["prior"] == "skinned":
            sa = torch.from_numpy(np.stack([seq.skin_window(s0, need) for s0 in starts])).to(device)
        xa = torch.from_numpy(np.stack(xs)).to(device)
        if a.noise_std > 0:  # only the frames the rollout starts from are inputs; targets stay clean
            base_in = rollout_base(cfg, True) + 2
            xin = xa[:, :base_in] + a.noise_std * torch.randn_like(xa[:, :base_in])
            xa = torch.cat([xin, xa[:, base_in:]], dim=1)
        ca = None if cs[0] is None else torch.from_numpy(np.stack(cs)).to(device)
        pa = None
        if a.pins and seq.pinned is not None:
            pa = torch.from_numpy(np.stack([seq.pin_window(s0, need) for s0 in starts])).to(device)
        mesh = mc.get(seq)
        predt = model(xa, ca, mesh["rest"], mesh["adj"], mesh["ctri"], R, True, sa, pa)
        preds = predt.unbind(1)
        base = rollout_base(cfg, True)
        mse = 0.0
        contact = 0.0
        ccd_l = torch.zeros(())
        strain = torch.zeros((), device=device)
        ctri = mc.get(seq)["ctri"]
        for i, p in enumerate(preds):
            gt = xa[:, base + 2 + i]
            mse = mse + (((p - gt) / out_scale) ** 2).sum(-1).mean()
            if ca is not None:
                contact = contact + contact_penalty(p, ca[:, base + 2 + i], ctri)
            if a.lambda_strain > 0:
                strain = strain + strain_penalty(p, mesh["edges"], mesh["rest_len"])
            if ccd is not None:
                world = ccd_worlds.get(seq.folder)
                if world is None:
                    world = ccd.CCDWorld(seq.faces, seq.rest.shape[0])
                    ccd_worlds[seq.folder] = world
                prev = xa[:, base + 1 + i] if i == 0 else preds[i - 1]
                ccd_l = ccd_l + ccd_loss(world, prev, p, out_scale)
        loss = (mse + a.lambda_contact * contact + a.lambda_ccd * ccd_l + a.lambda_strain * strain) / len(preds)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
        opt.step()
        step += 1
        step_s = max(step_s, time.time() - t_step)
        mse_cm = math.sqrt(float(mse) / len(preds)) * out_scale * 100.0
        run_avg = mse_cm if run_avg is None else 0.98 * run_avg + 0.02 * mse_cm
        elapsed = elapsed_before + time.time() - t_start
        val_mve = ""
        if rank == 0 and a.eval_every > 0 and (step % a.eval_every == 0 or step == a.steps) and val:
            v = timed_eval()
            val_mve = f"{v:.4f}"
            if a.keep_best and v < best_val:
                best_val = v
                save_ckpt(os.path.join(a.out, "best.pt"), {"model": net.state_dict(), "config": cfg, "step": step,
                                                          "elapsed": elapsed, "val_mve_cm": v})
        if log:
            log.writerow([step, f"{float(loss):.6g}", f"{mse_cm:.5f}", f"{float(contact) / len(preds):.5g}",
                          f"{float(ccd_l):.5g}", R, f"{lr:.3g}", f"{elapsed:.1f}", val_mve, f"{float(strain) / len(preds):.5g}"])
        if rank == 0 and (tty or step % 50 == 0 or val_mve):
            frac = min(1.0, max(step / a.steps, progress))
            bar = "#" * int(30 * frac) + "-" * (30 - int(30 * frac))
            msg = (f"[{bar}] {step}/{a.steps} rms {run_avg:.3f} cm R={R} lr {lr:.2g} "
                   f"{elapsed / 60:.1f} min" + (f" val MVE {val_mve} cm" if val_mve else ""))
            print(("\r" + msg) if tty else msg, end="" if tty and not val_mve else "\n", file=sys.stderr, flush=True)
        if rank == 0 and a.snapshot_every > 0 and step % a.snapshot_every == 0:
            save_ckpt(os.path.join(a.out, f"snap_{step:06d}.pt"), {"model": net.state_dict(), "config": cfg,
                                                                  "step": step, "elapsed": elapsed})
        out_of_time = a.max_minutes > 0 and (time.time() - t_start) + reserve_s() > 60 * a.max_minutes
        if rank == 0 and (step % a.ckpt_every == 0 or step == a.steps or out_of_time):
            save_ckpt(ckpt_path, {"model": net.state_dict(), "opt": opt.state_dict(), "step": step,
                                  "config": cfg, "elapsed": elapsed, "py_rng": random.getstate(),
                                  "torch_rng": torch.get_rng_state()})
            logf.flush()
        if ddp:
            flag = torch.tensor([1 if out_of_time else 0])
            dist.all_reduce(flag)
            out_of_time = bool(flag.item())
        if out_of_time:
            if rank == 0:
                print(f"\nstopped at step {step} (--max-minutes); rerun with --resume", file=sys.stderr)
            break
    if rank == 0:
        if a.budget_minutes > 0:  # the budget ended the loop between checkpoints: save the last step
            save_ckpt(ckpt_path, {"model": net.state_dict(), "opt": opt.state_dict(), "step": step,
                                  "config": cfg, "elapsed": elapsed_before + time.time() - t_start,
                                  "py_rng": random.getstate(), "torch_rng": torch.get_rng_state()})
            if val:
                v = evaluate(net, val, mc, device, a.eval_frames, a.pins)
                print(f"\nfinal val MVE {v:.4f} cm", file=sys.stderr)
                if a.keep_best and v < best_val:
                    save_ckpt(best_path, {"model": net.state_dict(), "config": cfg, "step": step,
                                          "elapsed": elapsed_before + time.time() - t_start, "val_mve_cm": v})
        elif a.max_minutes > 0 and a.eval_every > 0 and val and step % a.eval_every != 0:
            v = evaluate(net, val, mc, device, a.eval_frames, a.pins)  # where --max-minutes stopped it
            print(f"\nfinal val MVE {v:.4f} cm", file=sys.stderr)
            if log:
                log.writerow([step, "", "", "", "", "", "", f"{elapsed_before + time.time() - t_start:.1f}", f"{v:.4f}", ""])
            if a.keep_best and v < best_val:
                save_ckpt(best_path, {"model": net.state_dict(), "config": cfg, "step": step,
                                      "elapsed": elapsed_before + time.time() - t_start, "val_mve_cm": v})
        if logf:
            logf.flush()
        print(f"\ndone: step {step}, checkpoint {ckpt_path}", file=sys.stderr)
    if ddp:
        dist.destroy_process_group()


if __name__ == "__main__":
    main()
