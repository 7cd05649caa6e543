"""ctypes binding of weft's XPBD method (include/weft.h garments) for the "xpbd" prior.

The prior of a model with `"prior": "xpbd"` is one frame of the runtime's XPBD method at
`prior_substeps` substeps, restarted from (X_t, X_{t-1}) with the collider at t and t+1 and the
pins, without CCD. Training calls the very solver the runtime calls (the same shared library,
found as weft_ccd.py finds it), so prior and runtime agree bit for bit on the same float inputs.

    sim = XpbdPrior(rest, faces, collider_rest, collider_faces, substeps=1)
    y = sim.step(x_t, x_prev, c_t, c_next, pin_idx, pin_targets)      # (V, 3) float32

A garment is not thread-safe; `PriorPool` keeps one solver per (sequence, worker) and steps a
batch on a thread pool (ctypes releases the GIL while the C step runs).
"""

import ctypes
from concurrent.futures import ThreadPoolExecutor

import numpy as np

import weft_ccd

METHOD_XPBD = 1


class _TetherDef(ctypes.Structure):
    _fields_ = [("distance", ctypes.c_float), ("distances", ctypes.c_void_p)]


class _AttachmentDef(ctypes.Structure):
    _fields_ = [("enabled", ctypes.c_bool), ("slack", ctypes.c_float)]


class _StrainLimitDef(ctypes.Structure):
    _fields_ = [("limit", ctypes.c_float), ("iterations", ctypes.c_uint32), ("contact", ctypes.c_float)]


class _CollisionDef(ctypes.Structure):
    _fields_ = [
        ("push", ctypes.c_float),
        ("push_depth", ctypes.c_float),
        ("triangle_parts", ctypes.c_void_p),
        ("part_margin", ctypes.c_float),
        ("cut_distance", ctypes.c_float),
        ("part_neighbours", ctypes.c_bool),
        ("ground", ctypes.c_bool),
        ("ground_height", ctypes.c_float),
    ]


class _CcdDef(ctypes.Structure):
    _fields_ = [("enabled", ctypes.c_bool), ("iterations", ctypes.c_uint32)]


class _GarmentDef(ctypes.Structure):
    _fields_ = [
        ("method", ctypes.c_int),
        ("model", ctypes.c_void_p),
        ("precision", ctypes.c_int),
        ("rest_positions", ctypes.c_void_p),
        ("vertex_count", ctypes.c_uint32),
        ("triangles", ctypes.c_void_p),
        ("triangle_count", ctypes.c_uint32),
        ("collider_rest_positions", ctypes.c_void_p),
        ("collider_vertex_count", ctypes.c_uint32),
        ("collider_triangles", ctypes.c_void_p),
        ("collider_triangle_count", ctypes.c_uint32),
        ("initial_positions", ctypes.c_void_p),
        ("substeps", ctypes.c_uint32),
        ("substeps_max", ctypes.c_uint32),
        ("collider_crop_margin", ctypes.c_float),
        ("collider_crop", ctypes.c_int),
        ("max_collider_tokens", ctypes.c_uint32),
        ("collider_cap", ctypes.c_int),
        ("tethers", _TetherDef),
        ("attachments", _AttachmentDef),
        ("strain", _StrainLimitDef),
        ("collision", _CollisionDef),
        ("ccd", _CcdDef),
        ("internal_cookie", ctypes.c_uint32),
    ]


_bound = False


def _library():
    global _bound
    lib = weft_ccd._library()
    if not _bound:
        vp, u32 = ctypes.c_void_p, ctypes.c_uint32
        lib.weft_default_garment_def.restype = _GarmentDef
        lib.weft_garment_create.argtypes = [vp, ctypes.POINTER(_GarmentDef), ctypes.POINTER(vp)]
        lib.weft_garment_destroy.argtypes = [vp]
        lib.weft_garment_set_state.argtypes = [vp, vp, vp]
        lib.weft_garment_set_collider.argtypes = [vp, vp]
        lib.weft_garment_set_collider_current.argtypes = [vp, vp]
        lib.weft_garment_set_pins.argtypes = [vp, vp, vp, u32]
        lib.weft_garment_step.argtypes = [vp]
        lib.weft_garment_positions.argtypes = [vp]
        lib.weft_garment_positions.restype = ctypes.POINTER(ctypes.c_float)
        _bound = True
    return lib


def _f32(a):
    return np.ascontiguousarray(a, dtype=np.float32)


class XpbdPrior:
    """One XPBD garment (no CCD) on fixed cloth and collider meshes, restarted every step."""

    def __init__(self, rest, faces, collider_rest=None, collider_faces=None, substeps=1):
        lib = _library()
        self._lib = lib
        self.nv = int(rest.shape[0])
        self._keep = [_f32(rest), np.ascontiguousarray(faces, dtype=np.uint32)]
        self._ctx = ctypes.c_void_p()
        cdef = lib.weft_default_context_def()
        cdef.max_workers = 1
        weft_ccd._check(lib.weft_context_create(ctypes.byref(cdef), ctypes.byref(self._ctx)), "weft_context_create")
        d = lib.weft_default_garment_def()
        d.method = METHOD_XPBD
        d.rest_positions = self._keep[0].ctypes.data
        d.vertex_count = self.nv
        d.triangles = self._keep[1].ctypes.data
        d.triangle_count = self._keep[1].size // 3
        self.cv = 0
        if collider_rest is not None and collider_faces is not None and len(collider_faces) > 0:
            cr, cf = _f32(collider_rest), np.ascontiguousarray(collider_faces, dtype=np.uint32)
            self._keep += [cr, cf]
            self.cv = int(cr.shape[0])
            d.collider_rest_positions = cr.ctypes.data
            d.collider_vertex_count = self.cv
            d.collider_triangles = cf.ctypes.data
            d.collider_triangle_count = cf.size // 3
        d.substeps = int(substeps)
        d.ccd.enabled = False
        self._g = ctypes.c_void_p()
        r = lib.weft_garment_create(self._ctx, ctypes.byref(d), ctypes.byref(self._g))
        if r != 0:
            self._g = None
            self.close()
            weft_ccd._check(r, "weft_garment_create (xpbd prior)")
        self._out = np.empty((self.nv, 3), dtype=np.float32)

    def step(self, x_t, x_prev, c_t=None, c_next=None, pin_idx=None, pin_targets=None):
        lib, g = self._lib, self._g
        x_t, x_prev = _f32(x_t), _f32(x_prev)
        weft_ccd._check(lib.weft_garment_set_state(g, x_t.ctypes.data, x_prev.ctypes.data), "set_state")
        if self.cv > 0:
            c_t, c_next = _f32(c_t), _f32(c_next)
            weft_ccd._check(lib.weft_garment_set_collider_current(g, c_t.ctypes.data), "set_collider_current")
            weft_ccd._check(lib.weft_garment_set_collider(g, c_next.ctypes.data), "set_collider")
        if pin_idx is not None and len(pin_idx) > 0:
            pi, pt = np.ascontiguousarray(pin_idx, dtype=np.uint32), _f32(pin_targets)
            weft_ccd._check(lib.weft_garment_set_pins(g, pi.ctypes.data, pt.ctypes.data, pi.size), "set_pins")
        else:
            weft_ccd._check(lib.weft_garment_set_pins(g, None, None, 0), "set_pins")
        weft_ccd._check(lib.weft_garment_step(g), "weft_garment_step (xpbd prior)")
        ctypes.memmove(self._out.ctypes.data, lib.weft_garment_positions(g), self._out.nbytes)
        return self._out.copy()

    def close(self):
        if getattr(self, "_g", None):
            self._lib.weft_garment_destroy(self._g)
            self._g = None
        if getattr(self, "_ctx", None):
            self._lib.weft_context_destroy(self._ctx)
            self._ctx = None

    def __del__(self):
        self.close()


class PriorPool:
    """XPBD priors for batches: one solver per (sequence key, worker), a thread pool over them."""

    def __init__(self, substeps, workers=1):
        self.substeps = int(substeps)
        self.workers = max(1, int(workers))
        self._sims = {}
        self._pool = ThreadPoolExecutor(self.workers) if self.workers > 1 else None

    def _sim(self, key, mesh, w):
        s = self._sims.get((key, w))
        if s is None:
            s = XpbdPrior(mesh["rest_np"], mesh["faces_np"], mesh.get("crest_np"), mesh.get("cfaces_np"),
                          self.substeps)
            self._sims[(key, w)] = s
        return s

    def batch(self, key, mesh, x_t, x_prev, c_t=None, c_next=None, pin_mask=None, pin_next=None):
        """x_t, x_prev (B, V, 3) numpy; c_t, c_next (B, C, 3) or None; pin_mask (B, V) bool and
        pin_next (B, V, 3) or None. Returns Y (B, V, 3) float32."""
        B = x_t.shape[0]

        def one(b, w):
            pi = pt = None
            if pin_mask is not None:
                pi = np.nonzero(pin_mask[b])[0]
                pt = pin_next[b][pi]
            return self._sim(key, mesh, w).step(x_t[b], x_prev[b], None if c_t is None else c_t[b],
                                                None if c_next is None else c_next[b], pi, pt)

        if self._pool is None or B == 1:
            return np.stack([one(b, 0) for b in range(B)])
        chunks = [list(range(w, B, self.workers)) for w in range(self.workers)]
        futs = [self._pool.submit(lambda bs, w: [(b, one(b, w)) for b in bs], bs, w)
                for w, bs in enumerate(chunks) if bs]
        out = [None] * B
        for f in futs:
            for b, y in f.result():
                out[b] = y
        return np.stack(out)
