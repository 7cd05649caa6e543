"""FNOpt in PyTorch: the grid-cloth physics loss, the FNO network and the learned-optimizer
wrapper, written to match weft's C runtime (runtime/fnopt) term by term.

Conventions (docs/FNOPT.md): state tensors are (B, 3, H, W) in grid units (rest edge length 1),
one time step is dt = 1, vertex index = i * W + j with i along H.
"""
import json
import math

import torch
import torch.nn as nn
import torch.nn.functional as F

# acos clamp: 1 - 1e-7 rounded to float32 is 1 - 2^-23; written as 2^-23 so float64 runs clamp
# at the same place. Straight grid lines get zero bending gradient.
ACOS_EPS = 2.0 ** -23


def lumped_mass(h, w, dtype=torch.float32):
    """1 inside, 0.5 on the border, 0.25 at the corners (unit squares split to their corners)."""
    mi = torch.ones(h, dtype=dtype)
    mi[0] = mi[-1] = 0.5
    mj = torch.ones(w, dtype=dtype)
    mj[0] = mj[-1] = 0.5
    return (mi[:, None] * mj[None, :]).reshape(1, 1, h, w)


def _angle(u, w):
    c = (u * w).sum(1)
    return torch.acos(torch.clamp(c, -1 + ACOS_EPS, 1 - ACOS_EPS))


def internal_energy(x_new, Y, S, B):
    """Stretch + shear + bend of positions (B,3,H,W); Y, S, B are (B,) tensors. Returns (B,)."""
    h, w = x_new.shape[-2:]
    n = h * w
    eI = x_new[:, :, 1:, :] - x_new[:, :, :-1, :]
    eJ = x_new[:, :, :, 1:] - x_new[:, :, :, :-1]
    lI = torch.linalg.vector_norm(eI, dim=1)
    lJ = torch.linalg.vector_norm(eJ, dim=1)
    e_stretch = Y * (((lI - 1.0) ** 2).mean((1, 2)) + ((lJ - 1.0) ** 2).mean((1, 2)))
    nI = F.normalize(eI, dim=1, eps=1e-12)
    nJ = F.normalize(eJ, dim=1, eps=1e-12)
    hp = 0.5 * math.pi
    a = nI[:, :, :, :-1]   # eI(i, j)      i <= H-2, j <= W-2
    b = nI[:, :, :, 1:]    # eI(i, j+1)
    c = nJ[:, :, :-1, :]   # eJ(i, j)
    d = nJ[:, :, 1:, :]    # eJ(i+1, j)
    shear = ((_angle(a, c) - hp) ** 2 + (_angle(a, d) - hp) ** 2 +
             (_angle(b, c) - hp) ** 2 + (_angle(b, d) - hp) ** 2).sum((1, 2))
    e_shear = S / n * shear
    bend = (_angle(nI[:, :, 1:, :], nI[:, :, :-1, :]) ** 2).sum((1, 2)) + \
           (_angle(nJ[:, :, :, 1:], nJ[:, :, :, :-1]) ** 2).sum((1, 2))
    e_bend = B / n * bend
    return e_stretch + e_shear + e_bend


def grid_triangle_edges(h, w):
    """Edge pairs (both orientations) of the grid split into triangles along the (i,j)-(i+1,j+1)
    diagonal: horizontal, vertical and that diagonal. Returns a (h*w, h*w) bool mask."""
    idx = torch.arange(h * w).reshape(h, w)
    pairs = [(idx[:, :-1], idx[:, 1:]), (idx[:-1, :], idx[1:, :]), (idx[:-1, :-1], idx[1:, 1:])]
    m = torch.zeros(h * w, h * w, dtype=torch.bool)
    for p, q in pairs:
        m[p.reshape(-1), q.reshape(-1)] = True
        m[q.reshape(-1), p.reshape(-1)] = True
    return m


_EDGE_MASK = {}


def repulsion_energy(x_new, thres=0.5, res=32):
    """M_rep of fnopt.md section 9: positions bilinearly resampled to res x res (align_corners),
    sum over ordered non-adjacent pairs closer than thres of -log(d^2 + 1e-8), / batch size."""
    xr = F.interpolate(x_new, (res, res), mode='bilinear', align_corners=True)
    p = xr.reshape(xr.shape[0], 3, -1).transpose(1, 2)           # (B, N, 3)
    d2 = ((p[:, :, None, :] - p[:, None, :, :]) ** 2).sum(-1) + 1e-8
    if res not in _EDGE_MASK:
        _EDGE_MASK[res] = grid_triangle_edges(res, res)
    excl = _EDGE_MASK[res] | torch.eye(res * res, dtype=torch.bool)
    mask = (d2 < thres * thres) & ~excl[None]
    e = torch.where(mask, -torch.log(d2), torch.zeros_like(d2))
    return e.sum((1, 2)) / x_new.shape[0]


def physics_loss(x_old, v_old, acc, f, m, bc, Y, S, B, k_rep=0.0, rep_thres=0.5):
    """Backward-Euler incremental potential per sample, shape (B,). f is an acceleration field
    broadcastable to (B,3,H,W); m (B,1,H,W) handle mask; bc (B,3,H,W) handle targets."""
    h, w = acc.shape[-2:]
    n = h * w
    M = lumped_mass(h, w, acc.dtype).to(acc.device)
    v_new = v_old + acc
    x_new = x_old + v_new
    x_new = m * bc + (1.0 - m) * x_new
    L = internal_energy(x_new, Y, S, B)
    L = L + 0.5 / n * (M * acc * acc).sum((1, 2, 3))
    L = L - 1.0 / n * (M * acc * f).sum((1, 2, 3))
    if k_rep > 0:
        L = L + k_rep * repulsion_energy(x_new, rep_thres)
    return L


def loss_grad(x_old, v_old, acc, f, m, bc, Y, S, B, k_rep=0.0):
    """Gradient of the batch-summed loss with respect to acc (what the optimizer sees)."""
    with torch.enable_grad():
        a = acc.detach().requires_grad_(True)
        L = physics_loss(x_old, v_old, a, f, m, bc, Y, S, B, k_rep)
        g, = torch.autograd.grad(L.sum(), a)
    return g.detach(), L.detach()


# ------------------------------------------------------------------------------------------
# FNO


class SpectralConv(nn.Module):
    """Truncated-mode spectral convolution (fnopt.md 4.1): kx in {-4..3}, ky in {0..4},
    rfft norm='forward', dense complex weight (in, out, 8, 5)."""

    def __init__(self, width, modes_h=8, modes_w=5):
        super().__init__()
        self.mh, self.mw = modes_h, modes_w
        std = math.sqrt(2.0 / (width + width))
        self.weight = nn.Parameter(torch.randn(width, width, modes_h, modes_w, 2) * std / math.sqrt(2))

    def forward(self, x):
        b, c, h, w = x.shape
        X = torch.fft.rfft2(x, norm='forward')                     # (b, c, h, w//2+1)
        half = self.mh // 2
        # kept rows in weight order m = 0..7 <-> frequency m - 4
        Xk = torch.cat([X[:, :, h - half:, :self.mw], X[:, :, :half, :self.mw]], dim=2)
        Wc = torch.view_as_complex(self.weight)
        Yk = torch.einsum('bixy,ioxy->boxy', Xk, Wc)
        out = torch.zeros(b, Wc.shape[1], h, w // 2 + 1, dtype=X.dtype, device=x.device)
        out[:, :, h - half:, :self.mw] = Yk[:, :, :half]
        out[:, :, :half, :self.mw] = Yk[:, :, half:]
        return torch.fft.irfft2(out, s=(h, w), norm='forward')


class FNO(nn.Module):
    """e11 layout: lifting 5->256->64, 4 spectral blocks (width 64) with linear skips, GELU
    between blocks, projection 64->64->1, scalar head Linear(amax(block 2 output))."""

    def __init__(self, width=64, lifting=256, projection=64, n_layers=4, modes_h=8, modes_w=5,
                 scale_feature_layer=2, in_channels=3):
        super().__init__()
        self.cfg = dict(width=width, lifting_channels=lifting, projection_channels=projection,
                        n_layers=n_layers, modes_h=modes_h, modes_w=modes_w,
                        scale_feature_layer=scale_feature_layer, in_channels=in_channels)
        self.lift0 = nn.Conv2d(in_channels + 2, lifting, 1)
        self.lift1 = nn.Conv2d(lifting, width, 1)
        self.spectral = nn.ModuleList([SpectralConv(width, modes_h, modes_w) for _ in range(n_layers)])
        self.spec_bias = nn.Parameter(torch.randn(n_layers, width) * 0.02)
        self.skips = nn.ModuleList([nn.Conv2d(width, width, 1, bias=False) for _ in range(n_layers)])
        self.proj0 = nn.Conv2d(width, projection, 1)
        self.proj1 = nn.Conv2d(projection, 1, 1)
        self.head = nn.Linear(width, 1)
        self.n_layers = n_layers
        self.sfl = scale_feature_layer

    def forward(self, z):
        b, _, h, w = z.shape
        gh = torch.linspace(0, 1, h, dtype=z.dtype, device=z.device).reshape(1, 1, h, 1).expand(b, 1, h, w)
        gw = torch.linspace(0, 1, w, dtype=z.dtype, device=z.device).reshape(1, 1, 1, w).expand(b, 1, h, w)
        x = torch.cat([z, gh, gw], 1)
        x = self.lift1(F.gelu(self.lift0(x)))
        feat = None
        for l in range(self.n_layers):
            x = self.spectral[l](x) + self.spec_bias[l].reshape(1, -1, 1, 1) + self.skips[l](x)
            if l < self.n_layers - 1:
                x = F.gelu(x)
            if l == self.sfl:
                feat = x
        d = self.head(feat.amax(dim=(2, 3)))
        u = self.proj1(F.gelu(self.proj0(x)))
        return u, d


class NormalizeGrads(torch.autograd.Function):
    """Identity forward; backward replaces the gradient by its per-sample unit-L2 version
    clamped to [-10, 10], making the training signal independent of the loss scale."""

    @staticmethod
    def forward(ctx, x):
        return x.view_as(x)

    @staticmethod
    def backward(ctx, g):
        dims = tuple(range(1, g.dim()))
        nrm = torch.sqrt((g * g).sum(dims, keepdim=True)).clamp_min(1e-40)
        return (g / nrm).clamp(-10, 10)


def normalize_grads(x):
    return NormalizeGrads.apply(x)


def _soft(x, std):
    return 10.0 * torch.tanh(x / std / 10.0)


def optimizer_step(net, g, g_prev, s_prev, scale, train=False):
    """One learned-optimizer update for single-channel samples.
    g, g_prev, s_prev: (N,1,H,W); scale: (N,1). Returns (step, new_scale)."""
    n_pix = g.shape[-1] * g.shape[-2]
    dims = (1, 2, 3)
    gd = g.detach()
    grad_std = torch.sqrt((gd * gd).sum(dims, keepdim=True)).clamp_min(1e-40) / math.sqrt(n_pix)
    step_std = torch.sqrt((s_prev * s_prev).sum(dims, keepdim=True)).clamp_min(1e-40) / math.sqrt(n_pix)
    z = torch.cat([_soft(gd, grad_std), _soft(g_prev, grad_std), _soft(s_prev, step_std)], 1)
    u, d = net(z)
    u = torch.tanh(u)
    e = 2.0 * torch.tanh(d / 2.0) - 1.0
    if train:
        u = normalize_grads(u)
        e = normalize_grads(e)
    new_scale = scale * torch.exp(e)
    step = u * new_scale.reshape(-1, 1, 1, 1)
    return step, new_scale


def to_channels(t):
    """(B,3,H,W) -> (3B,1,H,W): x, y, z components become independent samples."""
    b, c, h, w = t.shape
    return t.reshape(b * c, 1, h, w)


def from_channels(t, b):
    n, _, h, w = t.shape
    return t.reshape(b, n // b, h, w)


def save_safetensors(path, tensors, metadata):
    """Minimal safetensors writer (F32 little-endian), tensors in sorted-name order."""
    import numpy as np
    header = {"__metadata__": metadata}
    blobs = []
    off = 0
    for name in sorted(tensors):
        a = np.ascontiguousarray(tensors[name].detach().cpu().numpy().astype('<f4'))
        nb = a.nbytes
        header[name] = {"dtype": "F32", "shape": list(a.shape), "data_offsets": [off, off + nb]}
        blobs.append(a.tobytes())
        off += nb
    hb = json.dumps(header, separators=(',', ':')).encode()
    hb += b' ' * ((8 - len(hb) % 8) % 8)
    with open(path, 'wb') as fh:
        fh.write(len(hb).to_bytes(8, 'little'))
        fh.write(hb)
        for blob in blobs:
            fh.write(blob)


def export_tensors(net):
    """Network parameters under the names the C runtime binds (runtime/fnopt/fno.c)."""
    t = {}
    t['lift0.weight'] = net.lift0.weight.reshape(net.lift0.weight.shape[0], -1)
    t['lift0.bias'] = net.lift0.bias
    t['lift1.weight'] = net.lift1.weight.reshape(net.lift1.weight.shape[0], -1)
    t['lift1.bias'] = net.lift1.bias
    for l in range(net.n_layers):
        t[f'blocks.{l}.spectral.weight'] = net.spectral[l].weight      # (in, out, 8, 5, 2) re/im
        t[f'blocks.{l}.bias'] = net.spec_bias[l]
        t[f'blocks.{l}.skip.weight'] = net.skips[l].weight.reshape(net.skips[l].weight.shape[0], -1)
    t['proj0.weight'] = net.proj0.weight.reshape(net.proj0.weight.shape[0], -1)
    t['proj0.bias'] = net.proj0.bias
    t['proj1.weight'] = net.proj1.weight.reshape(1, -1)
    t['proj1.bias'] = net.proj1.bias
    t['head.weight'] = net.head.weight
    t['head.bias'] = net.head.bias
    return t


def export_model(net, path, name='fnopt', extra=None):
    cfg = dict(net.cfg)
    cfg.update(dict(initial_scale=0.05, grid_embedding='linspace_endpoint', gelu='erf',
                    fft_norm='forward', skip='linear'))
    if extra:
        cfg.update(extra)
    meta = {"architecture": "fnopt", "name": name, "config": json.dumps(cfg, sort_keys=True)}
    save_safetensors(path, export_tensors(net), meta)


def load_safetensors(path):
    """Reads a safetensors file written by save_safetensors: (tensors as numpy, metadata)."""
    import numpy as np
    with open(path, 'rb') as fh:
        hl = int.from_bytes(fh.read(8), 'little')
        header = json.loads(fh.read(hl))
        data = fh.read()
    meta = header.pop('__metadata__', {})
    out = {}
    for name, e in header.items():
        a, b = e['data_offsets']
        out[name] = np.frombuffer(data[a:b], dtype='<f4').reshape(e['shape']).copy()
    return out, meta


def import_model(path):
    """An FNO with the weights of an exported fnopt safetensors file."""
    t, meta = load_safetensors(path)
    cfg = json.loads(meta['config'])
    net = FNO(width=cfg['width'], lifting=cfg['lifting_channels'], projection=cfg['projection_channels'],
              n_layers=cfg['n_layers'], modes_h=cfg['modes_h'], modes_w=cfg['modes_w'],
              scale_feature_layer=cfg['scale_feature_layer'], in_channels=cfg['in_channels'])
    T = lambda k: torch.from_numpy(t[k])  # noqa: E731
    with torch.no_grad():
        net.lift0.weight.copy_(T('lift0.weight').reshape(net.lift0.weight.shape))
        net.lift0.bias.copy_(T('lift0.bias'))
        net.lift1.weight.copy_(T('lift1.weight').reshape(net.lift1.weight.shape))
        net.lift1.bias.copy_(T('lift1.bias'))
        for l in range(net.n_layers):
            net.spectral[l].weight.copy_(T(f'blocks.{l}.spectral.weight'))
            net.spec_bias[l].copy_(T(f'blocks.{l}.bias'))
            net.skips[l].weight.copy_(T(f'blocks.{l}.skip.weight').reshape(net.skips[l].weight.shape))
        net.proj0.weight.copy_(T('proj0.weight').reshape(net.proj0.weight.shape))
        net.proj0.bias.copy_(T('proj0.bias'))
        net.proj1.weight.copy_(T('proj1.weight').reshape(net.proj1.weight.shape))
        net.proj1.bias.copy_(T('proj1.bias'))
        net.head.weight.copy_(T('head.weight'))
        net.head.bias.copy_(T('head.bias'))
    return net, cfg


class Rollout:
    """Inference stepping of one cloth (batch 1), the reference for the C runtime:
    K learned iterations with the target handle positions in every iteration, then the update."""

    def __init__(self, net, x0, Y, S, B, gravity, mask, k_rep=0.0, scale0=0.05, dtype=torch.float64):
        self.net = net.to(dtype)
        self.dt = dtype
        self.x = x0.to(dtype).clone()
        self.v = torch.zeros_like(self.x)
        self.h, self.w = x0.shape[-2:]
        self.mask = mask.to(dtype)
        self.bc = torch.zeros_like(self.x)
        self.Y = torch.tensor([Y], dtype=dtype)
        self.S = torch.tensor([S], dtype=dtype)
        self.B = torch.tensor([B], dtype=dtype)
        self.f = torch.tensor(gravity, dtype=dtype).reshape(1, 3, 1, 1)
        self.k_rep = k_rep
        self.g_prev = torch.zeros(3, 1, self.h, self.w, dtype=dtype)
        self.s_prev = torch.zeros(3, 1, self.h, self.w, dtype=dtype)
        self.scale = torch.full((3, 1), scale0, dtype=dtype)

    @torch.no_grad()
    def step(self, bc, K, trace=None):
        self.bc = bc.to(self.dt)
        acc = torch.zeros_like(self.x)
        for _ in range(K):
            g, _ = loss_grad(self.x, self.v, acc, self.f, self.mask, self.bc, self.Y, self.S, self.B, self.k_rep)
            gc = to_channels(g)
            step, self.scale = optimizer_step(self.net, gc, self.g_prev, self.s_prev, self.scale)
            acc = acc + from_channels(step, 1)
            self.g_prev, self.s_prev = gc, step
            if trace is not None:
                trace.append(acc.clone())
        self.v = self.v + acc
        xn = self.x + self.v
        self.v = self.mask * (self.bc - self.x) + (1 - self.mask) * self.v
        self.x = self.mask * self.bc + (1 - self.mask) * xn
        return acc


def grid_to_c(t):
    """(1,3,H,W) -> (H*W, 3) numpy float32, the C runtime's layout."""
    return t[0].permute(1, 2, 0).reshape(-1, 3).detach().cpu().numpy().astype('<f4')


def c_to_grid(a, h, w):
    return torch.from_numpy(a.reshape(h, w, 3)).permute(2, 0, 1)[None]
