"""make_sphere.py - a UV sphere of about 2 * N * N triangles with normals, for
measuring load memory of imported models (docs/meshes.md, "Smooth shading").
  python3 bench/gltf/make_sphere.py N OUT.glb smooth   # indexed, a normal per vertex (as exporters write)
  python3 bench/gltf/make_sphere.py N OUT.glb flat     # a vertex per corner, the face's normal at each
  python3 bench/gltf/make_sphere.py N OUT.obj smooth   # OBJ with vn, for a "model" shape (Assimp)"""
import json
import math
import struct
import sys


def sphere(n):
    verts = []
    for i in range(n + 1):
        th = math.pi * i / n
        for j in range(n + 1):
            ph = 2 * math.pi * j / n
            verts.append((math.sin(th) * math.cos(ph), math.cos(th), math.sin(th) * math.sin(ph)))
    tris = []
    for i in range(n):
        for j in range(n):
            a, b = i * (n + 1) + j, i * (n + 1) + j + 1
            c, d = a + n + 1, b + n + 1
            if i > 0:
                tris.append((a, b, c))
            if i < n - 1:
                tris.append((b, d, c))
    return verts, tris


def glb(path, pos, nor, idx):
    nv = len(pos)
    bp = b"".join(struct.pack("<3f", *p) for p in pos)
    bn = b"".join(struct.pack("<3f", *p) for p in nor)
    bi = struct.pack("<%dI" % len(idx), *idx) if idx else b""
    bin_ = bp + bn + bi
    acc = [{"bufferView": 0, "componentType": 5126, "count": nv, "type": "VEC3",
            "min": [min(p[k] for p in pos) for k in range(3)], "max": [max(p[k] for p in pos) for k in range(3)]},
           {"bufferView": 1, "componentType": 5126, "count": nv, "type": "VEC3"}]
    views = [{"buffer": 0, "byteOffset": 0, "byteLength": len(bp)},
             {"buffer": 0, "byteOffset": len(bp), "byteLength": len(bn)}]
    prim = {"attributes": {"POSITION": 0, "NORMAL": 1}}
    if idx:
        views.append({"buffer": 0, "byteOffset": len(bp) + len(bn), "byteLength": len(bi)})
        acc.append({"bufferView": 2, "componentType": 5125, "count": len(idx), "type": "SCALAR"})
        prim["indices"] = 2
    doc = {"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [prim]}], "buffers": [{"byteLength": len(bin_)}],
           "bufferViews": views, "accessors": acc}
    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    with open(path, "wb") as f:
        f.write(struct.pack("<3I", 0x46546C67, 2, 12 + 8 + len(js) + 8 + len(bin_)))
        f.write(struct.pack("<2I", len(js), 0x4E4F534A) + js)
        f.write(struct.pack("<2I", len(bin_), 0x004E4942) + bin_)


def main():
    n, out, kind = int(sys.argv[1]), sys.argv[2], sys.argv[3]
    verts, tris = sphere(n)
    if out.endswith(".obj"):
        with open(out, "w") as f:
            f.writelines("v %.7f %.7f %.7f\n" % v for v in verts)
            f.writelines("vn %.7f %.7f %.7f\n" % v for v in verts)
            f.writelines("f %d//%d %d//%d %d//%d\n" % (a + 1, a + 1, b + 1, b + 1, c + 1, c + 1) for a, b, c in tris)
    elif kind == "smooth":
        glb(out, verts, verts, [k for t in tris for k in t])
    else:
        pos, nor = [], []
        for t in tris:
            p = [verts[k] for k in t]
            e1 = [p[1][i] - p[0][i] for i in range(3)]
            e2 = [p[2][i] - p[0][i] for i in range(3)]
            c = (e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0])
            l = math.sqrt(sum(x * x for x in c)) or 1
            pos += p
            nor += [tuple(x / l for x in c)] * 3
        glb(out, pos, nor, None)
    print("%s: %d triangles" % (out, len(tris)))


main()
