"""ClothTransformer (latent-space transformer cloth simulator) in PyTorch.

The layer set is deliberately restricted to what the C runtime implements in runtime/kernels:
Linear (+bias, +GELU-tanh), LayerNorm, softmax attention with a boolean mask, SwiGLU, mean
aggregation over mesh edges and a sinusoidal embedding with fixed frequencies. Every tensor name in
the state dict is the name the C forward pass (runtime/model/transformer.c) looks up.

Data flow for one step t -> t+1 (all positions in metres, centred on the garment centroid at t):
  encoder:  cloth vertices  [pe(X_t - c), (X_t - X_{t-1}) * vel_scale] -> MLP -> 2 x GNN -> tokens
            collider tris   [pe(3 corners), corner velocities, normal, area] -> MLP -> tokens
            K learned queries cross-attend to both token sets -> Z_t (K x D)
  temporal: window of `history` latents (+ slot embedding), block-causal pre-norm transformer with
            SwiGLU feed-forward; the newest frame's output is Z_{t+1}
  decoder:  rest-shape vertices -> pe -> MLP -> queries cross-attending to Z_{t+1}
            (+ the encoder's vertex tokens when dec_skip) -> 2 x GNN -> Linear -> displacement
  output:   X_{t+1} = prior + out_scale * displacement, prior = X_t + S_{t+1} - S_t ("skinned": S
            is the skinning baseline on the collider, runtime/geometry/skin.c; X_t when the
            collider does not move; with prior_decay a < 1, S_{t+1} + a (X_t - S_t)) or
            X_t + beta (X_t - X_{t-1}) + g dt^2 ("ballistic": free fall is in the prior; beta 1
            and gravity_step 0 give the inertial 2 X_t - X_{t-1}, beta 0 X_t) or
            X_t + beta (X_t - X_{t-1}) kept within each vertex's rest distance of the pins' centroid
            ("grasp": a long-range attachment to the hand, P the pins' targets at t+1)
"""
import json
import math

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

ARCHITECTURE = "clothtransformer"

DEFAULT_CONFIG = {
    "K": 64,              # learned latent queries
    "D": 64,              # width of every token
    "L": 2,               # temporal transformer layers
    "H": 4,               # attention heads (all attention blocks)
    "history": 1,         # latent frames the temporal transformer sees
    "ffn": 128,           # SwiGLU hidden width in the temporal transformer
    "nfreq": 6,           # sinusoidal frequencies per coordinate
    "freq_base": 2.0,     # rad/m of the lowest frequency; frequency f is freq_base * 2^f
    "gnn_layers": 2,      # encoder and decoder GNN depth
    "vel_scale": 100.0,   # multiplies X_t - X_{t-1} (m/frame) before the velocity embedding
    "area_scale": 100.0,  # multiplies sqrt(triangle area) (m) of collider triangles
    "out_scale": 0.01,    # metres per unit of the decoder output
    "prior": "skinned",   # "skinned" (X_t + S_{t+1} - S_t), "ballistic" (X_t + prior_beta (X_t - X_{t-1})
                          # - gravity_step along Y), "grasp" (as ballistic without gravity, then every vertex
                          # kept within its rest distance of the pinned vertices' centroid: a long-range
                          # attachment to the hand)
    "prior_beta": 1.0,    # ballistic and grasp priors: fraction of the last frame's displacement carried on
    "prior_decay": 1.0,   # skinned prior: S_{t+1} + prior_decay (X_t - S_t), the offset from the skinned
                          # garment kept per step (1: X_t + S_{t+1} - S_t; < 1: drift decays toward it)
    "gravity_step": 9.81 / 3600.0,  # ballistic prior: g dt^2 (m) at 60 Hz, applied along -Y
    "attach_output": False,  # grasp prior: the attachment to the hand bounds the output (prior plus
                             # displacement), not the prior alone
    "crop_margin": 0.15,  # collider triangles farther than this (m) from the garment box are dropped
    "dec_skip": True,     # decoder adds the encoder's per-vertex tokens to its queries' output
    "requires_collider": False,  # set by training when every training sequence had a collider
    "ln_eps": 1e-5,
}

GELU_TANH = "tanh"
PRIORS = ("skinned", "ballistic", "grasp")
# Keys no model uses any more; a checkpoint may carry them at these values, which change nothing.
INERT_KEYS = {"prior_substeps": 1, "velocity_from_prior": False}


def full_config(cfg):
    out = dict(DEFAULT_CONFIG)
    out.update(cfg or {})
    for k, v in INERT_KEYS.items():
        if k in out and out.pop(k) != v:
            raise ValueError(f"config key {k!r} is not supported (only {v!r})")
    if out["D"] % out["H"] != 0:
        raise ValueError("D must be a multiple of H")
    if out["prior"] not in PRIORS:
        raise ValueError("prior must be one of " + ", ".join(PRIORS))
    if not 0.0 <= out["prior_decay"] <= 1.0:
        raise ValueError("prior_decay must be in [0, 1]")
    return out


# ---------------------------------------------------------------------------------------------
# Mesh helpers (shared with the data pipeline and export)

def mesh_edges(faces, n):
    """Undirected unique edges of a triangle mesh as an (E, 2) int64 array, i < j."""
    f = np.asarray(faces, dtype=np.int64)
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]], axis=0)
    e = np.sort(e, axis=1)
    e = np.unique(e, axis=0)
    return e


def mean_adjacency(faces, n):
    """Sparse (n x n) row-normalised adjacency: (A @ h)[i] = mean of h over i's mesh neighbours."""
    e = mesh_edges(faces, n)
    rows = np.concatenate([e[:, 0], e[:, 1]])
    cols = np.concatenate([e[:, 1], e[:, 0]])
    deg = np.bincount(rows, minlength=n).astype(np.float32)
    vals = 1.0 / np.maximum(deg[rows], 1.0)
    idx = torch.from_numpy(np.stack([rows, cols]))
    return torch.sparse_coo_tensor(idx, torch.from_numpy(vals.astype(np.float32)), (n, n)).coalesce()


def posembed(x, freqs):
    """x (..., d) -> (..., d * F * 2) laid out [(d*F + f)*2 + {0: sin, 1: cos}] as the C kernel."""
    a = x.unsqueeze(-1) * freqs                              # (..., d, F)
    s = torch.stack([torch.sin(a), torch.cos(a)], dim=-1)    # (..., d, F, 2)
    return s.flatten(-3)


def triangle_features(c_next, c_cur, ctri, centre, freqs, vel_scale, area_scale):
    """Per collider triangle: pe of its 3 corners, corner velocities, unit normal, sqrt(area)."""
    p = c_next[..., ctri, :]                      # (B, M, 3, 3)
    v = (c_next - c_cur)[..., ctri, :] * vel_scale
    e1 = p[..., 1, :] - p[..., 0, :]
    e2 = p[..., 2, :] - p[..., 0, :]
    cr = torch.cross(e1, e2, dim=-1)
    a2 = torch.sqrt((cr * cr).sum(-1, keepdim=True) + 1e-20)
    n = cr / a2
    area = torch.sqrt(0.5 * a2) * area_scale
    pe = posembed(p - centre.unsqueeze(-2), freqs)  # (B, M, 3, 6F)
    return torch.cat([pe.flatten(-2), v.flatten(-2), n, area], dim=-1)


def crop_mask(x_t, c_next, ctri, margin):
    """(B, M) bool: collider triangle whose box at t+1 overlaps the garment box at t grown by margin."""
    lo = x_t.min(dim=-2).values - margin          # (B, 3)
    hi = x_t.max(dim=-2).values + margin
    p = c_next[..., ctri, :]                      # (B, M, 3, 3)
    tlo = p.min(dim=-2).values
    thi = p.max(dim=-2).values
    return ((tlo <= hi.unsqueeze(-2)) & (thi >= lo.unsqueeze(-2))).all(dim=-1)


# ---------------------------------------------------------------------------------------------
# Blocks

class MLP2(nn.Module):
    """Linear -> GELU(tanh) -> Linear."""

    def __init__(self, din, dh, dout):
        super().__init__()
        self.fc1 = nn.Linear(din, dh)
        self.fc2 = nn.Linear(dh, dout)

    def forward(self, x):
        return self.fc2(F.gelu(self.fc1(x), approximate=GELU_TANH))


class GNNLayer(nn.Module):
    """h <- h + MLP([h, mean over mesh neighbours of h])."""

    def __init__(self, d):
        super().__init__()
        self.mlp = MLP2(2 * d, d, d)

    def forward(self, h, adj):
        # h: (B, N, D); adj: sparse (N, N)
        B, N, D = h.shape
        flat = h.transpose(0, 1).reshape(N, B * D)
        agg = torch.sparse.mm(adj, flat).reshape(N, B, D).transpose(0, 1)
        return h + self.mlp(torch.cat([h, agg], dim=-1))


def attention(q, k, v, heads, key_mask=None, attn_mask=None):
    """q (B, Nq, D), k/v (B, Nk, D). key_mask (B, Nk) bool keep; attn_mask (Nq, Nk) bool keep."""
    B, Nq, D = q.shape
    Nk = k.shape[1]
    dh = D // heads
    qh = q.view(B, Nq, heads, dh).transpose(1, 2)
    kh = k.view(B, Nk, heads, dh).transpose(1, 2)
    vh = v.view(B, Nk, heads, dh).transpose(1, 2)
    s = (qh @ kh.transpose(-1, -2)) * (1.0 / math.sqrt(dh))
    if key_mask is not None:
        s = s.masked_fill(~key_mask[:, None, None, :], float("-inf"))
    if attn_mask is not None:
        s = s.masked_fill(~attn_mask[None, None], float("-inf"))
    p = torch.softmax(s, dim=-1)
    return (p @ vh).transpose(1, 2).reshape(B, Nq, D)


class CrossAttention(nn.Module):
    """x <- x + O(attn(Q(LN x), K(LN y), V(LN y))); x <- x + MLP(LN x)."""

    def __init__(self, d, heads, eps):
        super().__init__()
        self.heads = heads
        self.ln_q = nn.LayerNorm(d, eps=eps)
        self.ln_kv = nn.LayerNorm(d, eps=eps)
        self.q = nn.Linear(d, d)
        self.k = nn.Linear(d, d)
        self.v = nn.Linear(d, d)
        self.o = nn.Linear(d, d)
        self.ln_ff = nn.LayerNorm(d, eps=eps)
        self.ff = MLP2(d, 2 * d, d)

    def forward(self, x, y, key_mask=None):
        yn = self.ln_kv(y)
        a = attention(self.q(self.ln_q(x)), self.k(yn), self.v(yn), self.heads, key_mask=key_mask)
        x = x + self.o(a)
        return x + self.ff(self.ln_ff(x))


class TemporalLayer(nn.Module):
    """Pre-norm self-attention (block-causal over frames) + SwiGLU feed-forward."""

    def __init__(self, d, heads, ffn, eps):
        super().__init__()
        self.heads = heads
        self.ln1 = nn.LayerNorm(d, eps=eps)
        self.q = nn.Linear(d, d)
        self.k = nn.Linear(d, d)
        self.v = nn.Linear(d, d)
        self.o = nn.Linear(d, d)
        self.ln2 = nn.LayerNorm(d, eps=eps)
        self.gate = nn.Linear(d, ffn)
        self.up = nn.Linear(d, ffn)
        self.down = nn.Linear(ffn, d)

    def forward(self, x, mask):
        h = self.ln1(x)
        x = x + self.o(attention(self.q(h), self.k(h), self.v(h), self.heads, attn_mask=mask))
        h = self.ln2(x)
        return x + self.down(F.silu(self.gate(h)) * self.up(h))


# ---------------------------------------------------------------------------------------------

def attach(y, pin_mask, pin_next, rest):
    """The grasp prior's long-range attachment: every vertex of y (B, V, 3) farther from the
    centroid of the pinned vertices' targets than it is from their centroid at rest is pulled
    back to that distance (no pins: y unchanged)."""
    if pin_mask is None:
        return y
    if rest is None:
        raise ValueError("the grasp prior needs the rest positions")
    m = pin_mask.to(y.dtype).unsqueeze(-1)                        # (B, V, 1)
    n = m.sum(dim=1, keepdim=True).clamp(min=1.0)                 # (B, 1, 1)
    c = (pin_next * m).sum(dim=1, keepdim=True) / n               # (B, 1, 3)
    rest = rest.expand_as(y)
    rc = (rest * m).sum(dim=1, keepdim=True) / n
    r = (rest - rc).norm(dim=-1, keepdim=True)                    # (B, V, 1)
    d = y - c
    L = d.norm(dim=-1, keepdim=True)
    held = torch.where(L > r, c + d * (r / L.clamp(min=1e-12)), y)
    return torch.where(m.sum(dim=1, keepdim=True) > 0, held, y)


def prior_positions(cfg, x_t, x_prev, s_next=None, s_cur=None, pin_mask=None, pin_next=None, rest=None):
    """The prior of config `cfg` (B, V, 3), as runtime/model/transformer.c computes it: the
    network's displacement is added to it. Any float dtype (the data statistics use float64)."""
    p = cfg["prior"]
    if p == "grasp":
        # the cloth carries its velocity on, and a held cloth hangs from its hand: no vertex
        # ends farther from the pins' centroid at t+1 than it is from their centroid at rest
        # (a long-range attachment; the rest distance is a lower bound of the path in the cloth)
        y = x_t + cfg["prior_beta"] * (x_t - x_prev)
        return y if cfg["attach_output"] else attach(y, pin_mask, pin_next, rest)
    if p == "skinned":
        if s_next is None or s_cur is None:
            raise ValueError("the skinned prior needs the S track (S_t and S_{t+1})")
        a = cfg["prior_decay"]
        if a == 1.0:
            return x_t + (s_next - s_cur)
        return s_next + a * (x_t - s_cur)
    if p == "ballistic":
        g = torch.zeros(3, dtype=x_t.dtype, device=x_t.device)
        g[1] = -cfg["gravity_step"]
        return x_t + cfg["prior_beta"] * (x_t - x_prev) + g
    raise ValueError(f"unknown prior {p!r}")


class ClothTransformer(nn.Module):
    def __init__(self, cfg=None):
        super().__init__()
        c = full_config(cfg)
        self.cfg = c
        D, K, Fq, eps = c["D"], c["K"], c["nfreq"], c["ln_eps"]
        self.register_buffer("freqs", torch.tensor([c["freq_base"] * 2.0 ** f for f in range(Fq)],
                                                   dtype=torch.float32))
        # encoder
        self.enc_cloth = MLP2(6 * Fq + 3, D, D)
        self.enc_gnn = nn.ModuleList([GNNLayer(D) for _ in range(c["gnn_layers"])])
        self.enc_coll = MLP2(18 * Fq + 9 + 3 + 1, D, D)
        self.queries = nn.Parameter(torch.randn(K, D) * 0.5)
        self.enc_xattn = CrossAttention(D, c["H"], eps)
        # temporal
        self.time_embed = nn.Parameter(torch.zeros(c["history"], D))
        self.tmp = nn.ModuleList([TemporalLayer(D, c["H"], c["ffn"], eps) for _ in range(c["L"])])
        # decoder
        self.dec_rest = MLP2(6 * Fq, D, D)
        self.dec_xattn = CrossAttention(D, c["H"], eps)
        self.dec_gnn = nn.ModuleList([GNNLayer(D) for _ in range(c["gnn_layers"])])
        self.dec_ln = nn.LayerNorm(D, eps=eps)
        self.dec_head = nn.Linear(D, 3)
        nn.init.zeros_(self.dec_head.weight)
        nn.init.zeros_(self.dec_head.bias)

    # -- pieces -------------------------------------------------------------------------------

    def encode(self, x_t, x_prev, adj, c_next=None, c_cur=None, ctri=None):
        """Returns (Z_t (B, K, D), vertex tokens (B, N, D))."""
        c = self.cfg
        centre = x_t.mean(dim=-2, keepdim=True)                    # (B, 1, 3)
        f = torch.cat([posembed(x_t - centre, self.freqs), (x_t - x_prev) * c["vel_scale"]], dim=-1)
        h = self.enc_cloth(f)
        for g in self.enc_gnn:
            h = g(h, adj)
        tokens, key_mask = h, None
        if ctri is not None and ctri.shape[0] > 0:
            keep = crop_mask(x_t, c_next, ctri, c["crop_margin"])
            # only the triangles some window of the batch keeps are encoded (the others are masked
            # out of the attention anyway): the same result, at the cost of the crop, not the body
            sel = keep.any(dim=0).nonzero().squeeze(1)
            if sel.numel() < ctri.shape[0]:
                ctri, keep = ctri[sel], keep[:, sel]
            tf = triangle_features(c_next, c_cur, ctri, centre, self.freqs, c["vel_scale"], c["area_scale"])
            ct = self.enc_coll(tf)
            tokens = torch.cat([h, ct], dim=1)
            key_mask = torch.cat([torch.ones(h.shape[:2], dtype=torch.bool, device=h.device), keep], dim=1)
        q = self.queries.unsqueeze(0).expand(x_t.shape[0], -1, -1)
        z = self.enc_xattn(q, tokens, key_mask=key_mask)
        return z, h

    def temporal(self, zs):
        """zs: (B, history, K, D) oldest first -> Z_{t+1} (B, K, D)."""
        B, Hh, K, D = zs.shape
        x = (zs + self.time_embed[None, :, None, :]).reshape(B, Hh * K, D)
        # block-causal: a frame's tokens see their own frame and older ones (not a buffer: gloo
        # cannot broadcast bool tensors)
        blk = torch.arange(Hh, device=zs.device).repeat_interleave(K)
        mask = blk[:, None] >= blk[None, :]
        for layer in self.tmp:
            x = layer(x, mask)
        return x[:, (Hh - 1) * K:, :]

    def rest_tokens(self, rest):
        return self.dec_rest(posembed(rest - rest.mean(dim=-2, keepdim=True), self.freqs))

    def decode(self, z_next, rest, adj, skip):
        r = self.rest_tokens(rest).expand(z_next.shape[0], -1, -1)
        h = self.dec_xattn(r, z_next)
        if self.cfg["dec_skip"]:
            h = h + skip
        for g in self.dec_gnn:
            h = g(h, adj)
        return self.dec_head(self.dec_ln(h))

    def prior(self, x_t, x_prev, s_next=None, s_cur=None, pin_mask=None, pin_next=None, rest=None):
        return prior_positions(self.cfg, x_t, x_prev, s_next, s_cur, pin_mask, pin_next, rest)

    # -- one step ----------------------------------------------------------------------------

    def step(self, hist, x_t, x_prev, rest, adj, c_next=None, c_cur=None, ctri=None, s_next=None, s_cur=None,
             pin_mask=None, pin_next=None):
        """hist: list of past latents (B, K, D) (oldest first, may be empty: reset); s_next/s_cur:
        the S track at t+1 and t (the skinned prior only); pin_mask (B, V) bool and pin_next
        (B, V, 3): the vertices pinned at t+1 and their targets (the grasp prior only). Returns
        (x_next, new hist list)."""
        z, vtok = self.encode(x_t, x_prev, adj, c_next, c_cur, ctri)
        hist = (list(hist) + [z])[-self.cfg["history"]:]
        while len(hist) < self.cfg["history"]:
            hist = [hist[0]] + hist            # repeat the oldest after a reset
        z_next = self.temporal(torch.stack(hist, dim=1))
        d = self.decode(z_next, rest, adj, vtok)
        x_next = self.prior(x_t, x_prev, s_next, s_cur, pin_mask, pin_next, rest) + self.cfg["out_scale"] * d
        if self.cfg["prior"] == "grasp" and self.cfg["attach_output"]:
            x_next = attach(x_next, pin_mask, pin_next, rest)
        return x_next, hist

    def metadata(self, name=""):
        return {"architecture": ARCHITECTURE, "name": name, "config": json.dumps(self.cfg, sort_keys=True)}


def export_tensors(model):
    """State dict with the names the C runtime expects (float32, contiguous numpy)."""
    out = {}
    for k, v in model.state_dict().items():
        out[k] = v.detach().cpu().float().contiguous().numpy()
    return out
