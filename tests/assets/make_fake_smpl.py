#!/usr/bin/python3
"""Writes synthetic SMPL-format .npz files and the posed vertices a plain numpy (float64)
implementation of the SMPL forward model gives for a few poses.

    /usr/bin/python3 make_fake_smpl.py OUT_DIR

OUT_DIR/fake_smpl_dense.npz   v_template f8, f u4, weights f8, J_regressor dense f8,
                              kintree_table u4 (root 2^32-1), shapedirs f4 fortran-ordered,
                              posedirs f8
OUT_DIR/fake_smpl_sparse.npz  v_template f4 fortran-ordered, f i8, weights f4, J_regressor as
                              scipy-style CSC arrays, kintree_table i8 (root -1), shapedirs f8,
                              no posedirs
OUT_DIR/corrupt_<case>.npz      damaged variants of the dense file (see CORRUPT below)
OUT_DIR/fuzz_corpus/*.npz       tiny archives (12 vertices) seeding the npz fuzz target
OUT_DIR/expected_{dense,sparse}.npz  betas (K,10), poses (K,72), trans (K,3), verts (K,V,3),
                              joints (K,24,3) posed joint positions

The arrays are random but valid: no real body is involved (SMPL files are licence-restricted).
"""
import io
import os
import sys
import zipfile

import numpy as np

PARENTS = [-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21]
NJ = 24
NV = 400
NB = 10


def rodrigues(aa):
    """(N,3) axis-angle -> (N,3,3) rotation matrices."""
    theta = np.linalg.norm(aa, axis=1)
    out = np.zeros((aa.shape[0], 3, 3))
    for i, (v, t) in enumerate(zip(aa, theta)):
        if t < 1e-12:
            out[i] = np.eye(3)
            continue
        k = v / t
        kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        out[i] = np.eye(3) + np.sin(t) * kx + (1 - np.cos(t)) * kx @ kx
    return out


def forward(model, betas, pose, trans):
    v_shaped = model["v_template"] + np.einsum("vcb,b->vc", model["shapedirs"], betas)
    joints = model["J_regressor"] @ v_shaped
    rots = rodrigues(pose.reshape(NJ, 3))
    v_posed = v_shaped
    if model.get("posedirs") is not None:
        feat = (rots[1:] - np.eye(3)).reshape(-1)
        v_posed = v_shaped + np.einsum("vcp,p->vc", model["posedirs"], feat)
    world = np.zeros((NJ, 4, 4))
    for j in range(NJ):
        local = np.eye(4)
        local[:3, :3] = rots[j]
        p = PARENTS[j]
        local[:3, 3] = joints[j] - (joints[p] if p >= 0 else 0)
        world[j] = local if p < 0 else world[p] @ local
    rel = world.copy()
    rel[:, :3, 3] -= np.einsum("jab,jb->ja", world[:, :3, :3], joints)
    per_vertex = np.einsum("vj,jab->vab", model["weights"], rel)
    verts = np.einsum("vab,vb->va", per_vertex[:, :3, :3], v_posed) + per_vertex[:, :3, 3] + trans
    return verts, world[:, :3, 3] + trans


def make_model(rng, nv=NV):
    # Joints of a rough upright figure, vertices scattered around them.
    joints = rng.normal(0, 0.3, (NJ, 3))
    owner = rng.integers(0, NJ, nv)
    v = joints[owner] + rng.normal(0, 0.05, (nv, 3))
    faces = []
    while len(faces) < 2 * nv:
        tri = rng.choice(nv, 3, replace=False)
        a, b, c = v[tri]
        if np.linalg.norm(np.cross(b - a, c - a)) > 1e-4:
            faces.append(tri)
    faces = np.array(faces)
    # Weights: each vertex bound to its owner and two random joints.
    w = np.zeros((nv, NJ))
    for i in range(nv):
        js = np.unique(np.concatenate([[owner[i]], rng.integers(0, NJ, 2)]))
        w[i, js] = rng.dirichlet(np.ones(len(js)))
    reg = np.zeros((NJ, nv))
    for j in range(NJ):
        idx = rng.choice(nv, 6, replace=False)
        reg[j, idx] = rng.dirichlet(np.ones(6))
    return {
        "v_template": v,
        "f": faces,
        "weights": w,
        "J_regressor": reg,
        "shapedirs": rng.normal(0, 0.01, (nv, 3, NB)),
        "posedirs": rng.normal(0, 0.005, (nv, 3, 9 * (NJ - 1))),
    }


def poses(rng):
    out = []
    out.append((np.zeros(NB), np.zeros(72), np.zeros(3)))
    out.append((rng.normal(0, 1, NB), rng.normal(0, 0.2, 72), np.array([0.1, -0.2, 0.3])))
    out.append((rng.normal(0, 2, NB), rng.normal(0, 1.0, 72), np.array([-1.0, 0.5, 2.0])))
    big = rng.normal(0, 1.0, 72)
    big[3:6] = [0, 0, 3.0]  # near-pi rotation
    big[6:9] = [1e-7, 0, 0]  # tiny rotation
    out.append((np.zeros(NB), big, np.zeros(3)))
    return out


def npy_bytes(arr):
    buf = io.BytesIO()
    np.save(buf, arr)
    return buf.getvalue()


def write_npz(path, entries):
    """entries: name -> raw .npy bytes (lets the corrupt cases write broken headers)."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED) as z:
        for name, data in entries.items():
            z.writestr(name + ".npy", data)


def corrupt_cases(dense):
    """name -> entries. The C test knows the expected error of each by name."""
    good = {k: npy_bytes(v) for k, v in dense.items()}
    cases = {}

    def variant(name, **changes):
        e = dict(good)
        for k, v in changes.items():
            if v is None:
                del e[k]
            else:
                e[k] = v
        cases[name] = e

    w = good["weights"]
    variant("npy_magic", weights=b"\x93NUMPZ" + w[6:])
    variant("npy_version", weights=w[:6] + bytes([9, 0]) + w[8:])
    hdr_len = int.from_bytes(w[8:10], "little")
    header = w[10:10 + hdr_len].decode("ascii")
    variant("npy_header_key", weights=w[:10] + header.replace("descr", "dtype").encode() + w[10 + hdr_len:])
    variant("npy_header_order", weights=w[:10] + header.replace("False", "Maybe").encode() + w[10 + hdr_len:])
    variant("npy_header_len", weights=w[:8] + (60000).to_bytes(2, "little") + w[10:])
    variant("npy_truncated_data", weights=w[:-8])
    variant("npy_shape_vs_data", weights=w[:10] + header.replace("(%d, 24)" % NV, "(%d, 24)" % (NV + 1)).encode()
            + w[10 + hdr_len:])
    variant("dtype_string", weights=npy_bytes(np.array(["abc"] * 4)))
    variant("dtype_big_endian", v_template=npy_bytes(dense["v_template"].astype(">f8")))
    variant("weights_shape", weights=npy_bytes(dense["weights"][:, :23]))
    variant("regressor_joints", J_regressor=npy_bytes(dense["J_regressor"][:23]))
    variant("kintree_joints", kintree_table=npy_bytes(np.zeros((2, 25), dtype=np.int64)))
    variant("faces_range", f=npy_bytes(np.full((4, 3), NV + 5, dtype=np.int32)))
    variant("posedirs_shape", posedirs=npy_bytes(dense["posedirs"][:, :, :200]))
    variant("missing_template", v_template=None)
    nan_v = dense["v_template"].copy()
    nan_v[3, 1] = np.nan
    variant("nan_template", v_template=npy_bytes(nan_v))
    return cases


def main():
    out_dir = sys.argv[1]
    os.makedirs(out_dir, exist_ok=True)
    rng = np.random.default_rng(1234)
    model = make_model(rng)

    # Dense variant. What C reads is float32 for some arrays: the expected values use the
    # values as stored (rounded) so the comparison measures the forward model only.
    dense = {
        "v_template": model["v_template"].astype(np.float64),
        "f": model["f"].astype(np.uint32),
        "weights": model["weights"].astype(np.float64),
        "J_regressor": model["J_regressor"].astype(np.float64),
        "kintree_table": np.array([[4294967295] + PARENTS[1:], list(range(NJ))], dtype=np.uint32),
        "shapedirs": np.asfortranarray(model["shapedirs"].astype(np.float32)),
        "posedirs": model["posedirs"].astype(np.float64),
    }
    np.savez(os.path.join(out_dir, "fake_smpl_dense.npz"), **dense)

    csc_ptr = [0]
    csc_idx, csc_val = [], []
    reg = model["J_regressor"]
    for col in range(NV):
        rows = np.nonzero(reg[:, col])[0]
        csc_idx.extend(rows)
        csc_val.extend(reg[rows, col])
        csc_ptr.append(len(csc_idx))
    sparse = {
        "v_template": np.asfortranarray(model["v_template"].astype(np.float32)),
        "f": model["f"].astype(np.int64),
        "weights": model["weights"].astype(np.float32),
        "J_regressor_data": np.array(csc_val, dtype=np.float64),
        "J_regressor_indices": np.array(csc_idx, dtype=np.int32),
        "J_regressor_indptr": np.array(csc_ptr, dtype=np.int32),
        "J_regressor_shape": np.array([NJ, NV], dtype=np.int64),
        "kintree_table": np.array([[-1] + PARENTS[1:], list(range(NJ))], dtype=np.int64),
        "shapedirs": model["shapedirs"].astype(np.float64),
    }
    np.savez_compressed(os.path.join(out_dir, "fake_smpl_sparse.npz"), **sparse)

    for name, entries in corrupt_cases(dense).items():
        write_npz(os.path.join(out_dir, "corrupt_%s.npz" % name), entries)

    # Fuzz seeds: the same layouts at 12 vertices (a few kB each), stored and deflated.
    fuzz_dir = os.path.join(out_dir, "fuzz_corpus")
    os.makedirs(fuzz_dir, exist_ok=True)
    tiny = make_model(np.random.default_rng(99), 12)
    tiny_arrays = {
        "v_template": tiny["v_template"],
        "f": tiny["f"].astype(np.int32),
        "weights": tiny["weights"].astype(np.float32),
        "J_regressor": np.asfortranarray(tiny["J_regressor"]),
        "kintree_table": np.array([[-1] + PARENTS[1:], list(range(NJ))], dtype=np.int64),
        "shapedirs": tiny["shapedirs"][:, :, :2].astype(np.float32),
    }
    np.savez(os.path.join(fuzz_dir, "tiny_dense.npz"), **tiny_arrays)
    np.savez_compressed(os.path.join(fuzz_dir, "tiny_deflated.npz"), **tiny_arrays)

    cases = poses(rng)
    for name, arrays in (("dense", dense), ("sparse", sparse)):
        m = {
            "v_template": arrays["v_template"].astype(np.float32).astype(np.float64),
            "weights": arrays["weights"].astype(np.float32).astype(np.float64),
            "J_regressor": reg.astype(np.float32).astype(np.float64),
            "shapedirs": arrays["shapedirs"].astype(np.float32).astype(np.float64),
            "posedirs": arrays["posedirs"].astype(np.float32).astype(np.float64) if "posedirs" in arrays else None,
        }
        verts, joints = [], []
        for betas, pose, trans in cases:
            b = betas.astype(np.float32).astype(np.float64)
            p = pose.astype(np.float32).astype(np.float64)
            t = trans.astype(np.float32).astype(np.float64)
            v, j = forward(m, b, p, t)
            verts.append(v)
            joints.append(j)
        np.savez(os.path.join(out_dir, "expected_%s.npz" % name),
                 betas=np.array([c[0] for c in cases], dtype=np.float32),
                 poses=np.array([c[1] for c in cases], dtype=np.float32),
                 trans=np.array([c[2] for c in cases], dtype=np.float32),
                 verts=np.array(verts), joints=np.array(joints))


if __name__ == "__main__":
    main()
