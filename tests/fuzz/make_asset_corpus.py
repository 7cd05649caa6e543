#!/usr/bin/python3
"""Regenerates the seed corpora of the asset fuzz targets: tests/fuzz/corpus/{bvh,npz,gltf,pc2}/.

Every seed is small (a few KB at most) so libFuzzer mutates whole files quickly:
  bvh   BVH clips of a few frames, one per skeleton naming the importer knows (CMU, collar,
        3ds Max, Mixamo, SMPL), plus rejected ones. cmu_01_01.bvh is CMU clip 01_01 (Debian's
        assimp-testmodels) cut to four frames with values rounded to two decimals.
  npz   the fake SMPL archives of tests/assets/make_fake_smpl.py (12 vertices, random numbers,
        no real body) and lone .npy images of every dtype the reader converts.
  gltf  skinned meshes written here: glTF with an embedded base64 buffer, binary .glb and ASCII
        FBX; one carries the 24 SMPL joint names so weft_skinned_to_clip succeeds.
  pc2   point caches, valid and broken (signature, version, size, NaN, count overflow).
Files named crash_* are not written here: they are inputs the fuzzer found failing (crash or
property), kept as found, next to the generated seeds.

Run: /usr/bin/python3 tests/fuzz/make_asset_corpus.py [CMU_01_01.bvh]"""
import base64
import io
import json
import math
import os
import struct
import sys
import zipfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
CORPUS = os.path.join(HERE, "corpus")

# SMPL-24: parents and a neutral rest pose (metres, feet on y = 0), as in runtime/assets/bvh.c.
PARENTS = [-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21]
REST = np.array([
    -0.002, 0.977, 0.028, 0.068, 0.885, 0.021, -0.070, 0.886, 0.024, -0.004, 1.086, 0.002,
    0.102, 0.510, 0.017, -0.108, 0.504, 0.015, 0.001, 1.221, 0.003, 0.088, 0.112, -0.027,
    -0.092, 0.105, -0.027, 0.003, 1.274, 0.028, 0.115, 0.056, 0.092, -0.117, 0.057, 0.096,
    -0.000, 1.488, -0.015, 0.082, 1.396, -0.006, -0.079, 1.393, -0.011, 0.005, 1.553, 0.036,
    0.172, 1.426, -0.015, -0.175, 1.425, -0.020, 0.432, 1.413, -0.043, -0.429, 1.412, -0.041,
    0.681, 1.422, -0.044, -0.684, 1.420, -0.047, 0.765, 1.414, -0.059, -0.769, 1.414, -0.057,
]).reshape(24, 3)
SMPL_NAMES = ["pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2", "left_ankle",
              "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar", "right_collar", "head",
              "left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
              "left_hand", "right_hand"]
SMPL_SHORT = ["Pelvis", "L_Hip", "R_Hip", "Spine1", "L_Knee", "R_Knee", "Spine2", "L_Ankle", "R_Ankle", "Spine3",
              "L_Foot", "R_Foot", "Neck", "L_Collar", "R_Collar", "Head", "L_Shoulder", "R_Shoulder", "L_Elbow",
              "R_Elbow", "L_Wrist", "R_Wrist", "L_Hand", "R_Hand"]
COLLAR = ["Hips", "LeftHip", "RightHip", "Ab", "LeftKnee", "RightKnee", "Chest", "LeftAnkle", "RightAnkle", "Chest2",
          "LeftToes", "RightToes", "Neck", "LeftCollar", "RightCollar", "Head", "LeftShoulder", "RightShoulder",
          "LeftElbow", "RightElbow", "LeftWrist", "RightWrist", "LeftHand", "RightHand"]
MAX3DS = ["Hips", "LeftHip", "RightHip", "lowerback", "LeftKnee", "RightKnee", "Chest", "LeftAnkle", "RightAnkle",
          "Chest2", "LeftToe", "RightToe", "lowerneck", "LeftCollar", "RightCollar", "Head", "LeftShoulder",
          "RightShoulder", "LeftElbow", "RightElbow", "LeftWrist", "RightWrist", "lhand", "rhand"]
CMU = ["Hips", "LeftUpLeg", "RightUpLeg", "LowerBack", "LeftLeg", "RightLeg", "Spine", "LeftFoot", "RightFoot", "Spine1",
       "LeftToeBase", "RightToeBase", "Neck", "LeftShoulder", "RightShoulder", "Head", "LeftArm", "RightArm",
       "LeftForeArm", "RightForeArm", "LeftHand", "RightHand", "LeftFingerBase", "RightFingerBase"]
MIXAMO = ["Hips", "LeftUpLeg", "RightUpLeg", "Spine", "LeftLeg", "RightLeg", "Spine1", "LeftFoot", "RightFoot",
          "Spine2", "LeftToeBase", "RightToeBase", "Neck", "LeftShoulder", "RightShoulder", "Head", "LeftArm",
          "RightArm", "LeftForeArm", "RightForeArm", "LeftHand", "RightHand", "LeftHandMiddle1", "RightHandMiddle1"]


def write(folder, name, data):
    path = os.path.join(CORPUS, folder)
    os.makedirs(path, exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(path, name), "wb") as f:
        f.write(data)


def num(v, digits=2):
    s = f"{v:.{digits}f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


# ---------------------------------------------------------------------------------------------
# BVH


def bvh_text(names, parents, offsets, frames, frame_time=0.0333, root_channels="Xposition Yposition Zposition "
             "Zrotation Xrotation Yrotation", channels="Zrotation Xrotation Yrotation", declared=None):
    """names/parents/offsets: joints in depth-first order. frames: rows of values."""
    children = {i: [j for j, p in enumerate(parents) if p == i] for i in range(len(names))}
    out = ["HIERARCHY"]

    def emit(i, depth):
        pad = " " * depth
        out.append(f"{pad}{'ROOT' if parents[i] < 0 else 'JOINT'} {names[i]}")
        out.append(pad + "{")
        out.append(f"{pad} OFFSET {' '.join(num(v) for v in offsets[i])}")
        spec = root_channels if parents[i] < 0 else channels
        out.append(f"{pad} CHANNELS {len(spec.split())} {spec}")
        for c in children[i]:
            emit(c, depth + 1)
        if not children[i]:
            out.append(f"{pad} End Site")
            out.append(pad + " {")
            out.append(f"{pad}  OFFSET 0 {num(0.05 if depth else 0)} 0")
            out.append(pad + " }")
        out.append(pad + "}")

    emit(0, 0)
    out.append("MOTION")
    out.append(f"Frames: {declared if declared is not None else len(frames)}")
    out.append(f"Frame Time: {frame_time}")
    for row in frames:
        out.append(" ".join(num(v, 1) for v in row))
    return "\n".join(out) + "\n"


def depth_first(parents):
    order = []

    def visit(i):
        order.append(i)
        for j, p in enumerate(parents):
            if p == i:
                visit(j)

    visit(0)
    return order


def smpl_skeleton(names, scale=1.0, helpers=None):
    """The SMPL tree under other joint names, in depth-first order, OFFSETs in the given unit.
    helpers: {smpl joint: name} puts a zero-length joint with no SMPL counterpart above that
    joint (like CMU's LHipJoint above LeftUpLeg)."""
    helpers = helpers or {}
    new_names, new_parents, offsets, index = [], [], [], {}
    for i in depth_first(PARENTS):
        p = PARENTS[i]
        parent = index[p] if p >= 0 else -1
        if i in helpers:
            new_names.append(helpers[i])
            new_parents.append(parent)
            offsets.append([0.0, 0.0, 0.0])
            parent = len(new_names) - 1
        index[i] = len(new_names)
        new_names.append(names[i])
        new_parents.append(parent)
        offsets.append(list((REST[i] - REST[p]) * scale if p >= 0 else REST[i] * scale))
    return new_names, new_parents, offsets


def motion(rng, joints, frames, root_height):
    rows = []
    for f in range(frames):
        row = [0.1 * f, root_height, 0.2 * f] + list(rng.uniform(-20, 20, 3))
        for _ in range(joints - 1):
            row += list(rng.uniform(-30, 30, 3))
        rows.append(row)
    return rows


def trim_cmu(path, frames=4):
    """A CMU BVH cut to `frames` frames, indentation and numbers shortened."""
    with open(path) as f:
        lines = f.read().splitlines()
    out = []
    i = 0
    while not lines[i].strip().startswith("MOTION"):
        raw = lines[i]
        depth = len(raw) - len(raw.lstrip("\t "))
        words = raw.split()
        if words and words[0] == "OFFSET":
            words = ["OFFSET"] + [num(float(v)) for v in words[1:]]
        out.append(" " * depth + " ".join(words))
        i += 1
    out += ["MOTION", f"Frames: {frames}", "Frame Time: 0.0083333"]
    for row in lines[i + 3:i + 3 + frames]:
        out.append(" ".join(num(float(v), 1) for v in row.split()))
    return "\n".join(out) + "\n"


def bvh_seeds(cmu_path):
    rng = np.random.default_rng(7)
    if cmu_path and os.path.exists(cmu_path):
        write("bvh", "cmu_01_01.bvh", trim_cmu(cmu_path))
    # CMU/MotionBuilder names with CMU's zero-length hip joints, in inches-like units
    names, parents, offsets = smpl_skeleton(CMU, 40.0, helpers={1: "LHipJoint", 2: "RHipJoint", 12: "Neck0"})
    write("bvh", "cmu_names.bvh", bvh_text(names, parents, offsets, motion(rng, len(names), 3, 38.0)))
    names, parents, offsets = smpl_skeleton(COLLAR, 100.0)
    write("bvh", "collar_names.bvh",
          bvh_text(names, parents, offsets, motion(rng, len(names), 2, 97.0), frame_time=0.01,
                   root_channels="Xposition Yposition Zposition Yrotation Xrotation Zrotation",
                   channels="Yrotation Xrotation Zrotation"))
    names, parents, offsets = smpl_skeleton(MAX3DS, 40.0)
    write("bvh", "max3ds_names.bvh", bvh_text(names, parents, offsets, motion(rng, len(names), 2, 38.0)))
    names, parents, offsets = smpl_skeleton(["mixamorig:" + n for n in MIXAMO], 100.0)
    write("bvh", "mixamo_names.bvh", bvh_text(names, parents, offsets, motion(rng, len(names), 3, 97.0),
                                              frame_time=0.0416667))
    names, parents, offsets = smpl_skeleton(SMPL_NAMES, 1.0)
    write("bvh", "smpl_names.bvh", bvh_text(names, parents, offsets, motion(rng, len(names), 2, 0.97)))
    names, parents, offsets = smpl_skeleton(SMPL_SHORT, 1.0)
    rows = motion(rng, len(names), 1, 0.97)
    write("bvh", "smpl_short_one_frame.bvh", bvh_text(names, parents, offsets, rows))
    # 20 of 24 joints: refused, naming the missing ones
    keep = [i for i in range(24) if i not in (10, 11, 22, 23)]
    sub_parents = [keep.index(PARENTS[i]) if PARENTS[i] >= 0 else -1 for i in keep]
    sub_names = [SMPL_NAMES[i] for i in keep]
    sub_offsets = [list((REST[i] - REST[PARENTS[i]]) if PARENTS[i] >= 0 else REST[i]) for i in keep]
    order = depth_first(sub_parents)
    remap = {old: new for new, old in enumerate(order)}
    write("bvh", "bad_too_few_joints.bvh",
          bvh_text([sub_names[i] for i in order], [remap[sub_parents[i]] if sub_parents[i] >= 0 else -1 for i in order],
                   [sub_offsets[i] for i in order], motion(rng, len(keep), 2, 0.97)))
    # three unknown joints, one frame
    small = bvh_text(["root", "a", "b"], [-1, 0, 1], [[0, 0, 0], [0, 1, 0], [0, 1, 0]],
                     [[0, 1, 0, 10, 0, 0, 5, 0, 0, 0, 5, 0]])
    write("bvh", "bad_unknown_skeleton.bvh", small)
    write("bvh", "bad_value_count.bvh", small.replace("Frames: 1", "Frames: 2"))
    write("bvh", "bad_nan.bvh", small.replace("10 0 0 5", "10 0 nan 5"))
    write("bvh", "bad_frame_time.bvh", small.replace("Frame Time: 0.0333", "Frame Time: 0"))
    write("bvh", "bad_braces.bvh", small.replace(" End Site\n", " End Site\n {\n", 1))


# ---------------------------------------------------------------------------------------------
# npz / npy


def npy(arr):
    buf = io.BytesIO()
    np.save(buf, arr, allow_pickle=False)
    return buf.getvalue()


def npz_seeds():
    sys.path.insert(0, os.path.join(HERE, "..", "assets"))
    import make_fake_smpl  # noqa: E402

    tiny = make_fake_smpl.make_model(np.random.default_rng(99), 12)
    arrays = {
        "v_template": tiny["v_template"],
        "f": tiny["f"].astype(np.int32),
        "weights": tiny["weights"].astype(np.float32),
        "J_regressor": np.asfortranarray(tiny["J_regressor"]),
        "kintree_table": np.array([[-1] + PARENTS[1:], list(range(24))], dtype=np.int64),
        "shapedirs": tiny["shapedirs"][:, :, :2].astype(np.float32),
    }
    for name, save in (("tiny_dense.npz", np.savez), ("tiny_deflated.npz", np.savez_compressed)):
        buf = io.BytesIO()
        save(buf, **arrays)
        write("npz", name, zipfile_fixed_times(buf.getvalue()))
    values = np.array([[1.5, -2.0, 0.25], [3.0, 4.0, -0.5]])
    for dtype in ("<f4", "<f8", ">f4", "<i4", "<i8", "<u4", "|u1", "<f2"):
        write("npz", f"array_{dtype.replace('<', 'le_').replace('>', 'be_').replace('|', '')}.npy",
              npy(values.astype(dtype)))
    write("npz", "array_fortran.npy", npy(np.asfortranarray(values.astype("<f4"))))
    write("npz", "array_scalar.npy", npy(np.float64(2.5)))
    write("npz", "bad_header.npy", npy(values.astype("<f4")).replace(b"'shape': (2, 3)", b"'shape': (9, 9)"))


def zipfile_fixed_times(data):
    """Rewrites a zip with fixed timestamps so regenerating gives identical bytes."""
    src = zipfile.ZipFile(io.BytesIO(data))
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as dst:
        for info in src.infolist():
            fixed = zipfile.ZipInfo(info.filename, date_time=(2020, 1, 1, 0, 0, 0))
            fixed.compress_type = info.compress_type
            dst.writestr(fixed, src.read(info.filename))
    return out.getvalue()


# ---------------------------------------------------------------------------------------------
# Skinned meshes: glTF, glb, FBX


def quat(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    s = math.sin(angle / 2)
    return [axis[0] * s, axis[1] * s, axis[2] * s, math.cos(angle / 2)]


class Gltf:
    """A minimal glTF 2.0 writer: one buffer, accessors appended as they are added."""

    def __init__(self):
        self.bin = bytearray()
        self.doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": []}], "nodes": [],
                    "meshes": [], "skins": [], "accessors": [], "bufferViews": [], "buffers": []}

    def accessor(self, array, ctype, gltf_type, minmax=False):
        raw = np.ascontiguousarray(array).tobytes()
        while len(self.bin) % 4:
            self.bin.append(0)
        self.doc["bufferViews"].append({"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(raw)})
        self.bin += raw
        count = len(array)
        acc = {"bufferView": len(self.doc["bufferViews"]) - 1, "componentType": ctype, "count": count,
               "type": gltf_type}
        if minmax:
            flat = np.asarray(array, float).reshape(count, -1)
            acc["min"] = [round(float(v), 6) for v in flat.min(axis=0)]
            acc["max"] = [round(float(v), 6) for v in flat.max(axis=0)]
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1

    def gltf(self):
        doc = dict(self.doc)
        doc["buffers"] = [{"byteLength": len(self.bin),
                           "uri": "data:application/octet-stream;base64," + base64.b64encode(self.bin).decode()}]
        return json.dumps(doc, separators=(",", ":"))

    def glb(self):
        doc = dict(self.doc)
        doc["buffers"] = [{"byteLength": len(self.bin)}]
        text = json.dumps(doc, separators=(",", ":")).encode()
        text += b" " * (-len(text) % 4)
        body = bytes(self.bin) + b"\0" * (-len(self.bin) % 4)
        total = 12 + 8 + len(text) + 8 + len(body)
        return (struct.pack("<4sII", b"glTF", 2, total) + struct.pack("<I4s", len(text), b"JSON") + text +
                struct.pack("<I4s", len(body), b"BIN\0") + body)


def skinned(names, parents, rest, vertices_per_joint, keys, animate, use_ibm=True, weights_scale=1.0, last_time=None):
    """A glTF with one node per joint (rest = world joint positions), a small mesh (a triangle
    at each listed joint, bound to it) and an animation of `keys` keys over the joints in
    `animate` (rotations) plus the root translation."""
    g = Gltf()
    n = len(names)
    for i in range(n):
        node = {"name": names[i]}
        t = rest[i] - rest[parents[i]] if parents[i] >= 0 else rest[i]
        node["translation"] = [round(float(v), 4) for v in t]
        kids = [j for j in range(n) if parents[j] == i]
        if kids:
            node["children"] = kids
        g.doc["nodes"].append(node)
    mesh_node = len(g.doc["nodes"])
    g.doc["nodes"].append({"name": "skin_mesh", "mesh": 0, "skin": 0})
    g.doc["scenes"][0]["nodes"] = [0, mesh_node]
    pos, joints, weights, tris = [], [], [], []
    for j in vertices_per_joint:
        base = len(pos)
        p = rest[j]
        pos += [p + [0.02, 0, 0], p + [-0.02, 0, 0], p + [0, 0.03, 0.01]]
        parent = parents[j] if parents[j] >= 0 else j
        joints += [[j, parent, 0, 0]] * 3
        weights += [[0.75 * weights_scale, 0.25 * weights_scale, 0, 0]] * 3
        tris += [base, base + 1, base + 2]
    a_pos = g.accessor(np.array(pos, "<f4"), 5126, "VEC3", minmax=True)
    a_idx = g.accessor(np.array(tris, "<u2"), 5123, "SCALAR")
    a_jnt = g.accessor(np.array(joints, "u1"), 5121, "VEC4")
    a_wgt = g.accessor(np.array(weights, "<f4"), 5126, "VEC4")
    g.doc["meshes"].append({"primitives": [{"attributes": {"POSITION": a_pos, "JOINTS_0": a_jnt, "WEIGHTS_0": a_wgt},
                                            "indices": a_idx, "mode": 4}]})
    skin = {"joints": list(range(n)), "skeleton": 0}
    if use_ibm:
        ibm = np.zeros((n, 16), "<f4")
        for i in range(n):
            m = np.eye(4)
            m[:3, 3] = -rest[i]
            ibm[i] = m.T.reshape(16)  # column-major
        skin["inverseBindMatrices"] = g.accessor(ibm, 5126, "MAT4")
    g.doc["skins"].append(skin)
    if keys:
        times = np.arange(keys, dtype="<f4") / 10.0
        if last_time is not None:
            times[-1] = last_time
        a_t = g.accessor(times, 5126, "SCALAR", minmax=True)
        samplers, channels = [], []
        for k, j in enumerate(animate):
            rot = np.array([quat([1, (k % 3) - 1, 0.5], 0.4 * f * (1 if k % 2 else -1)) for f in range(keys)], "<f4")
            samplers.append({"input": a_t, "output": g.accessor(rot, 5126, "VEC4"), "interpolation": "LINEAR"})
            channels.append({"sampler": len(samplers) - 1, "target": {"node": j, "path": "rotation"}})
        tr = np.array([rest[0] + [0.05 * f, 0, 0.1 * f] for f in range(keys)], "<f4")
        samplers.append({"input": a_t, "output": g.accessor(tr, 5126, "VEC3"), "interpolation": "LINEAR"})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": 0, "path": "translation"}})
        g.doc["animations"] = [{"samplers": samplers, "channels": channels}]
    return g


def fbx_ascii(keys=3):
    """An ASCII FBX 7.4 file: a triangle strip skinned to a two-bone chain, the tip bone
    rotating over `keys` keys."""
    ktime = 46186158000  # FBX ticks per second
    verts = [0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 2, 0, 1, 2, 0]
    poly = [0, 1, -4, 1, 3, -3, 2, 3, -6, 3, 5, -5]

    def arr(name, values, fmt=str):
        return f"\t\t{name}: *{len(values)} {{\n\t\t\ta: {','.join(fmt(v) for v in values)}\n\t\t}}\n"

    def matrix(ty):
        return [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, ty, 0, 1]

    def bone(uid, name, ty):
        return (f'\tModel: {uid}, "Model::{name}", "LimbNode" {{\n\t\tVersion: 232\n\t\tProperties70:  {{\n'
                f'\t\t\tP: "Lcl Translation", "Lcl Translation", "", "A",0,{ty},0\n\t\t}}\n\t}}\n'
                f'\tNodeAttribute: {uid + 1}, "NodeAttribute::{name}", "LimbNode" {{\n'
                f'\t\tTypeFlags: "Skeleton"\n\t}}\n')

    def cluster(uid, name, idx, w, ty):
        return (f'\tDeformer: {uid}, "SubDeformer::{name}", "Cluster" {{\n\t\tVersion: 100\n'
                + arr("Indexes", idx) + arr("Weights", w, num) + arr("Transform", matrix(-ty))
                + arr("TransformLink", matrix(ty)) + "\t}\n")

    out = ["; FBX 7.4.0 project file", "FBXHeaderExtension:  {", "\tFBXHeaderVersion: 1003", "\tFBXVersion: 7400",
           "}", "GlobalSettings:  {", "\tVersion: 1000", "\tProperties70:  {",
           '\t\tP: "UpAxis", "int", "Integer", "",1', '\t\tP: "UnitScaleFactor", "double", "Number", "",1',
           "\t}", "}", "Objects:  {"]
    text = "\n".join(out) + "\n"
    text += ('\tGeometry: 10, "Geometry::strip", "Mesh" {\n' + arr("Vertices", verts)
             + arr("PolygonVertexIndex", poly) + "\t\tGeometryVersion: 124\n\t}\n")
    text += '\tModel: 20, "Model::strip", "Mesh" {\n\t\tVersion: 232\n\t}\n'
    text += bone(30, "root", 0) + bone(40, "tip", 1)
    text += '\tDeformer: 50, "Deformer::skin", "Skin" {\n\t\tVersion: 101\n\t}\n'
    text += cluster(60, "root", [0, 1, 2, 3], [1, 1, 0.5, 0.5], 0)
    text += cluster(70, "tip", [2, 3, 4, 5], [0.5, 0.5, 1, 1], 1)
    if keys:
        text += '\tAnimationStack: 80, "AnimStack::bend", "" {\n\t}\n'
        text += '\tAnimationLayer: 90, "AnimLayer::base", "" {\n\t}\n'
        text += ('\tAnimationCurveNode: 100, "AnimCurveNode::R", "" {\n\t\tProperties70:  {\n'
                 '\t\t\tP: "d|X", "Number", "", "A",0\n\t\t\tP: "d|Y", "Number", "", "A",0\n'
                 '\t\t\tP: "d|Z", "Number", "", "A",0\n\t\t}\n\t}\n')
        text += ('\tAnimationCurve: 110, "AnimCurve::", "" {\n\t\tDefault: 0\n\t\tKeyVer: 4009\n'
                 + arr("KeyTime", [ktime * k // 10 for k in range(keys)])
                 + arr("KeyValueFloat", [15 * k for k in range(keys)])
                 + arr("KeyAttrFlags", [24840]) + arr("KeyAttrDataFloat", [0, 0, 218434821, 0])
                 + arr("KeyAttrRefCount", [keys]) + "\t}\n")
    text += "}\nConnections:  {\n"
    links = [("OO", 20, 0), ("OO", 10, 20), ("OO", 30, 0), ("OO", 40, 30), ("OO", 31, 30), ("OO", 41, 40),
             ("OO", 50, 10), ("OO", 60, 50), ("OO", 70, 50), ("OO", 30, 60), ("OO", 40, 70)]
    for kind, a, b in links:
        text += f'\tC: "{kind}",{a},{b}\n'
    if keys:
        text += '\tC: "OO",90,80\n\tC: "OO",100,90\n\tC: "OP",100,40, "Lcl Rotation"\n\tC: "OP",110,100, "d|Z"\n'
    return text + "}\n"


def gltf_seeds():
    smpl = skinned(SMPL_NAMES, PARENTS, REST, [0, 15, 20, 21, 7, 8], 3, [0, 1, 2, 16, 17])
    write("gltf", "smpl24_walk.gltf", smpl.gltf())
    short = skinned(SMPL_SHORT, PARENTS, REST, [0, 10, 11], 0, [])
    write("gltf", "smpl24_short_static.gltf", short.gltf())
    chain_rest = np.array([[0, 0, 0], [0, 0.5, 0], [0, 1.0, 0]], float)
    chain = skinned(["root", "mid", "tip"], [-1, 0, 1], chain_rest, [0, 1, 2], 4, [1, 2])
    write("gltf", "chain3_bend.gltf", chain.gltf())
    write("gltf", "chain3_bend.glb", chain.glb())
    write("gltf", "strip_skin.fbx", fbx_ascii())
    write("gltf", "strip_skin_static.fbx", fbx_ascii(keys=0))
    zero = skinned(["root", "mid", "tip"], [-1, 0, 1], chain_rest, [1], 0, [], weights_scale=0.0)
    write("gltf", "bad_zero_weights.gltf", zero.gltf())
    plain = skinned(["root", "mid", "tip"], [-1, 0, 1], chain_rest, [2], 0, [])
    del plain.doc["nodes"][-1]["skin"]
    plain.doc["skins"] = []
    write("gltf", "bad_no_skin.gltf", plain.gltf())
    # skins assimp 5.2 cannot read (weft refuses them before assimp sees them): no
    # inverseBindMatrices (a NULL dereference in assimp), and fewer matrices than joints
    no_ibm = skinned(SMPL_SHORT, PARENTS, REST, [0, 10, 11], 0, [], use_ibm=False)
    write("gltf", "bad_skin_without_ibm.gltf", no_ibm.gltf())
    short_ibm = skinned(["root", "mid", "tip"], [-1, 0, 1], chain_rest, [0, 1, 2], 0, [])
    short_ibm.doc["accessors"][short_ibm.doc["skins"][0]["inverseBindMatrices"]]["count"] = 2
    write("gltf", "bad_skin_short_ibm.glb", short_ibm.glb())
    # an animation of 1e30 s: refused (the frame count must not be computed from it)
    write("gltf", "bad_animation_too_long.gltf",
          skinned(["root", "mid", "tip"], [-1, 0, 1], chain_rest, [0, 1, 2], 3, [1], last_time=1e30).gltf())
    # FBX that would make assimp recurse without end: a connection cycle, scopes 80 deep
    write("gltf", "bad_cyclic_connections.fbx",
          fbx_ascii().replace('\tC: "OO",40,30\n', '\tC: "OO",40,30\n\tC: "OO",30,40\n'))
    write("gltf", "bad_deep_nesting.fbx",
          "; FBX 7.4.0 project file\nObjects:  {\n" + "A: {\n" * 80 + "}\n" * 80 + "}\n")


# ---------------------------------------------------------------------------------------------
# PC2


def pc2(points, samples, values=None, start=1.0, version=1, signature=b"POINTCACHE2\0", rate=1.0):
    head = signature + struct.pack("<IIffI", version, points, start, rate, samples)
    if values is None:
        values = np.linspace(-1, 1, points * samples * 3)
    return head + np.asarray(values, "<f4").tobytes()


def pc2_seeds():
    write("pc2", "one_point.pc2", pc2(1, 1, [0.5, 1.0, -2.0]))
    write("pc2", "three_points_two_samples.pc2", pc2(3, 2, start=10.0))
    write("pc2", "no_samples.pc2", pc2(4, 0))
    write("pc2", "bad_signature.pc2", pc2(1, 1, signature=b"POINTCACHE3\0"))
    write("pc2", "bad_version.pc2", pc2(1, 1, version=2))
    write("pc2", "bad_size.pc2", pc2(2, 2)[:-4])
    write("pc2", "bad_nan.pc2", pc2(1, 2, [0, 0, 0, 0, float("nan"), 0]))
    write("pc2", "bad_start_inf.pc2", pc2(1, 1, start=float("inf")))
    write("pc2", "bad_header.pc2", pc2(1, 1)[:20])
    # points x samples x 12 wraps around 2^64 to the 12 payload bytes (1380655685 x 3340214413
    # = 2^62 + 1): the count check must not be fooled by the overflow.
    write("pc2", "bad_count_overflow.pc2", pc2(1380655685, 3340214413, [1.0, 2.0, 3.0]))


def main():
    cmu = sys.argv[1] if len(sys.argv) > 1 else "/usr/share/assimp/models/BVH/01_01.bvh"
    bvh_seeds(cmu)
    npz_seeds()
    gltf_seeds()
    pc2_seeds()
    for folder in ("bvh", "npz", "gltf", "pc2"):
        path = os.path.join(CORPUS, folder)
        sizes = [os.path.getsize(os.path.join(path, f)) for f in sorted(os.listdir(path))]
        print(f"{folder}: {len(sizes)} seeds, largest {max(sizes)} bytes")


if __name__ == "__main__":
    main()
