"""ctypes binding of weft's CCD (include/weft/ccd.h) for the training CCD loss.

No compiled extension: the shared library (build*/lib/libweft.so) is loaded with ctypes. It is
found through the WEFT_LIB environment variable (a file path), else next to this repository
(build*/lib/libweft.so), else by the system loader.

    world = CCDWorld(cloth_triangles, cloth_vertex_count)           # self-collision only
    hits = world.detect(x0, x1, types="self")                       # numpy arrays
    x_safe = safe_positions(x0, x1, hits["vertices"], hits["toi"], eps=0.05)

`detect` returns the colliding pairs: "type" (K,) int32 (0 VF, 1 EE, 2 FV, 3 SELF_VF, 4 SELF_EE),
"vertices" (K, 4) int64 and "toi" (K,) float64, earliest contact times (conservative: never later
than the true contact). Loss of ClothTransformer Eq. 3 on the self types:
    L = mean_pairs 1/4 sum_j |x_end[v_j] - x_safe[v_j]|^2.
"""

import ctypes
import glob
import os

import numpy as np

TYPE_NAMES = ("vf", "ee", "fv", "self_vf", "self_ee")
MASK_COLLIDER = 0b00111
MASK_SELF = 0b11000
MASK_ALL = 0b11111


class _Allocator(ctypes.Structure):
    _fields_ = [("alloc", ctypes.c_void_p), ("free", ctypes.c_void_p), ("user", ctypes.c_void_p)]


class _ContextDef(ctypes.Structure):
    _fields_ = [
        ("allocator", _Allocator),
        ("parallel_for", ctypes.c_void_p),
        ("parallel_for_user", ctypes.c_void_p),
        ("max_workers", ctypes.c_uint32),
        ("isa", ctypes.c_int),
        ("internal_cookie", ctypes.c_uint32),
    ]


class _WorldDef(ctypes.Structure):
    _fields_ = [
        ("cloth_triangles", ctypes.c_void_p),
        ("cloth_triangle_count", ctypes.c_uint32),
        ("cloth_vertex_count", ctypes.c_uint32),
        ("collider_triangles", ctypes.c_void_p),
        ("collider_triangle_count", ctypes.c_uint32),
        ("collider_vertex_count", ctypes.c_uint32),
        ("cloth_layout_positions", ctypes.c_void_p),
        ("collider_layout_positions", ctypes.c_void_p),
        ("self_collision", ctypes.c_bool),
        ("min_separation", ctypes.c_double),
        ("time_margin", ctypes.c_double),
        ("max_iterations", ctypes.c_uint32),
        ("max_hits", ctypes.c_uint32),
        ("max_pairs", ctypes.c_uint64),
        ("internal_cookie", ctypes.c_uint32),
    ]


class _Report(ctypes.Structure):
    _fields_ = [
        ("hits", ctypes.c_uint32 * 5),
        ("hit_total", ctypes.c_uint32),
        ("hits_stored", ctypes.c_uint32),
        ("narrow_tests", ctypes.c_uint64),
        ("earliest_toi", ctypes.c_double),
    ]


class _PostStats(ctypes.Structure):
    _fields_ = [
        ("iterations", ctypes.c_uint32),
        ("vertices_moved", ctypes.c_uint32),
        ("vertices_carried", ctypes.c_uint32),
        ("vertices_held", ctypes.c_uint32),
        ("unresolved_hits", ctypes.c_uint32),
        ("fallback", ctypes.c_bool),
        ("held_all", ctypes.c_bool),
        ("over_budget", ctypes.c_bool),
        ("pairs_visited", ctypes.c_uint64),
    ]


_HIT_DTYPE = np.dtype([("type", "<u4"), ("v", "<u4", (4,)), ("toi", "<f8")], align=True)


def _find_library():
    env = os.environ.get("WEFT_LIB")
    if env:
        return env
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    for pattern in ("build/lib/libweft.so", "build*/lib/libweft.so"):
        found = sorted(glob.glob(os.path.join(root, pattern)))
        if found:
            return found[0]
    return "libweft.so"


_lib = None


def _library():
    global _lib
    if _lib is not None:
        return _lib
    lib = ctypes.CDLL(_find_library())
    vp, u32, f64 = ctypes.c_void_p, ctypes.c_uint32, ctypes.c_double
    lib.weft_default_context_def.restype = _ContextDef
    lib.weft_context_create.argtypes = [ctypes.POINTER(_ContextDef), ctypes.POINTER(vp)]
    lib.weft_context_destroy.argtypes = [vp]
    lib.weft_default_ccd_world_def.restype = _WorldDef
    lib.weft_ccd_world_create.argtypes = [vp, ctypes.POINTER(_WorldDef), ctypes.POINTER(vp)]
    lib.weft_ccd_world_destroy.argtypes = [vp]
    lib.weft_ccd_detect.argtypes = [vp, vp, vp, vp, vp, u32, ctypes.POINTER(_Report)]
    lib.weft_ccd_hits.argtypes = [vp, ctypes.POINTER(u32)]
    lib.weft_ccd_hits.restype = vp
    lib.weft_ccd_postprocess.argtypes = [vp, vp, vp, vp, vp, ctypes.POINTER(_PostStats)]
    lib.weft_ccd_vertex_face.argtypes = [vp, f64, ctypes.POINTER(f64)]
    lib.weft_ccd_edge_edge.argtypes = [vp, f64, ctypes.POINTER(f64)]
    lib.weft_last_error.restype = ctypes.c_char_p
    lib.weft_result_string.restype = ctypes.c_char_p
    lib.weft_result_string.argtypes = [ctypes.c_int]
    _lib = lib
    return lib


def _check(result, what):
    if result != 0:
        lib = _library()
        raise RuntimeError("%s failed: %s (%s)" % (what, lib.weft_result_string(result).decode(),
                                                    lib.weft_last_error().decode()))


def _f32(a, n, name):
    arr = np.ascontiguousarray(a, dtype=np.float32).reshape(-1)
    if arr.size != 3 * n:
        raise ValueError("%s: expected %d floats (%d vertices x 3), got %d" % (name, 3 * n, n, arr.size))
    return arr


def _query(fn, points, min_separation):
    p = np.ascontiguousarray(points, dtype=np.float64).reshape(-1)
    if p.size != 24:
        raise ValueError("a query is 8 points x 3 doubles")
    toi = ctypes.c_double(1.0)
    hit = fn(p.ctypes.data, float(min_separation), ctypes.byref(toi))
    return bool(hit), toi.value


def vertex_face(points, min_separation=0.0):
    """One vertex-face query: (hit, toi). points: (8, 3) vertex + triangle at t=0, then at t=1."""
    return _query(_library().weft_ccd_vertex_face, points, min_separation)


def edge_edge(points, min_separation=0.0):
    """One edge-edge query: (hit, toi). points: (8, 3) edge a + edge b at t=0, then at t=1."""
    return _query(_library().weft_ccd_edge_edge, points, min_separation)


def safe_positions(x0, x1, vertices, toi, eps=0.05):
    """x_safe = x0 + max(0, toi - eps) (x1 - x0) for every pair's 4 vertices: (K, 4, 3).

    Only valid for pairs whose four vertices are all cloth vertices (the self types)."""
    x0 = np.asarray(x0, dtype=np.float64).reshape(-1, 3)
    x1 = np.asarray(x1, dtype=np.float64).reshape(-1, 3)
    ts = np.maximum(0.0, np.asarray(toi, dtype=np.float64) - eps)[:, None, None]
    v = np.asarray(vertices, dtype=np.int64)
    return x0[v] + ts * (x1[v] - x0[v])


class CCDWorld:
    """A CCD world over fixed cloth (and optional collider) topology."""

    def __init__(self, cloth_triangles, cloth_vertex_count, collider_triangles=None, collider_vertex_count=0,
                 min_separation=1e-6, time_margin=0.05, max_iterations=16, max_hits=1 << 18):
        lib = _library()
        self._lib = lib
        self._ctx = ctypes.c_void_p()
        cdef = lib.weft_default_context_def()
        _check(lib.weft_context_create(ctypes.byref(cdef), ctypes.byref(self._ctx)), "weft_context_create")
        self._tris = np.ascontiguousarray(cloth_triangles, dtype=np.uint32).reshape(-1)
        self.nv = int(cloth_vertex_count)
        self.cv = int(collider_vertex_count)
        wdef = lib.weft_default_ccd_world_def()
        wdef.cloth_triangles = self._tris.ctypes.data
        wdef.cloth_triangle_count = self._tris.size // 3
        wdef.cloth_vertex_count = self.nv
        if collider_triangles is not None and self.cv > 0:
            self._ctris = np.ascontiguousarray(collider_triangles, dtype=np.uint32).reshape(-1)
            wdef.collider_triangles = self._ctris.ctypes.data
            wdef.collider_triangle_count = self._ctris.size // 3
            wdef.collider_vertex_count = self.cv
        wdef.min_separation = float(min_separation)
        wdef.time_margin = float(time_margin)
        wdef.max_iterations = int(max_iterations)
        wdef.max_hits = int(max_hits)
        self._world = ctypes.c_void_p()
        result = lib.weft_ccd_world_create(self._ctx, ctypes.byref(wdef), ctypes.byref(self._world))
        if result != 0:
            lib.weft_context_destroy(self._ctx)
            self._ctx = None
            _check(result, "weft_ccd_world_create")

    def close(self):
        if getattr(self, "_world", None):
            self._lib.weft_ccd_world_destroy(self._world)
            self._world = None
        if getattr(self, "_ctx", None):
            self._lib.weft_context_destroy(self._ctx)
            self._ctx = None

    def __del__(self):
        self.close()

    def _frames(self, x0, x1, c0, c1):
        a = _f32(x0, self.nv, "x0")
        b = _f32(x1, self.nv, "x1")
        if self.cv > 0 and c0 is not None and c1 is not None:
            return a, b, _f32(c0, self.cv, "c0"), _f32(c1, self.cv, "c1")
        return a, b, None, None

    def detect(self, x0, x1, c0=None, c1=None, types="self"):
        """Contacts while the cloth moves x0 -> x1 (and the collider c0 -> c1).

        types: "self", "collider", "all" or a bit mask. Returns a dict of numpy arrays:
        type (K,), vertices (K, 4), toi (K,), plus "counts" per type and "total"."""
        mask = {"self": MASK_SELF, "collider": MASK_COLLIDER, "all": MASK_ALL}.get(types, types)
        a, b, c, d = self._frames(x0, x1, c0, c1)
        rep = _Report()
        ptr = lambda arr: arr.ctypes.data if arr is not None else None
        _check(self._lib.weft_ccd_detect(self._world, ptr(a), ptr(b), ptr(c), ptr(d), int(mask), ctypes.byref(rep)),
               "weft_ccd_detect")
        n = ctypes.c_uint32()
        hp = self._lib.weft_ccd_hits(self._world, ctypes.byref(n))
        count = n.value
        if count:
            raw = (ctypes.c_char * (count * _HIT_DTYPE.itemsize)).from_address(hp)
            hits = np.frombuffer(raw, dtype=_HIT_DTYPE, count=count).copy()
        else:
            hits = np.zeros(0, dtype=_HIT_DTYPE)
        return {
            "type": hits["type"].astype(np.int32),
            "vertices": hits["v"].astype(np.int64),
            "toi": hits["toi"].astype(np.float64),
            "counts": dict(zip(TYPE_NAMES, list(rep.hits))),
            "total": int(rep.hit_total),
        }

    def postprocess(self, x0, x1, c0=None, c1=None):
        """The iterative CCD post-process; returns (new x1 as (N, 3) float32, stats dict)."""
        a, b, c, d = self._frames(x0, x1, c0, c1)
        b = b.copy()
        st = _PostStats()
        ptr = lambda arr: arr.ctypes.data if arr is not None else None
        result = self._lib.weft_ccd_postprocess(self._world, ptr(a), ptr(b), ptr(c), ptr(d), ctypes.byref(st))
        if result not in (0, _not_converged_code()):
            _check(result, "weft_ccd_postprocess")
        stats = {name: getattr(st, name) for name, _ in _PostStats._fields_}
        return b.reshape(-1, 3), stats


def _not_converged_code():
    """WEFT_ERROR_NOT_CONVERGED, looked up by its description so the enum order is not hard-coded."""
    lib = _library()
    for code in range(64):
        if lib.weft_result_string(code) == b"not converged":
            return code
    return -1
