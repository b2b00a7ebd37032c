#!/usr/bin/env python3
"""Writes the fuzz seed corpora into fuzz/seeds/<target>/ (run from anywhere).

scene_toml: scene files with every table and light kind; scene_gltf: small
.gltf/.glb files covering the loader's features, plus the repository's
small assets/*.glb; view_samples: inputs in the byte format that
fuzz_targets/view_samples.rs decodes, one per light kind.
"""
import base64, json, os, shutil, struct, zlib

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))


def out(target, name, data):
    d = os.path.join(HERE, target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


# --- scene_toml -------------------------------------------------------------
HEAD = 'scene = "builtin:plane_sphere"\n'
CAMERA = '[camera]\neye = [0.0, 2.0, 5.0]\ntarget = [0.0, 0.5, 0.0]\nup = [0.0, 1.0, 0.0]\nfov_y_deg = 45.0\nwidth = 64\nheight = 48\n'
LIGHTS = {
    "point": 'kind = "point"\nposition = [2.0, 5.0, 1.0]\n',
    "directional": 'kind = "directional"\ndirection = [0.3, -1.0, 0.2]\n',
    "sphere": 'kind = "sphere"\nposition = [2.0, 5.0, 1.0]\nradius = 0.5\nsamples = 64\ndistribution = "sobol"\nseed = 3\n',
    "disk": 'kind = "disk"\nposition = [0.0, 4.0, 0.0]\nradius = 0.4\nnormal = [0.0, -1.0, 0.0]\nsamples = 32\ndistribution = "stratified"\n',
    "disk_rotated": 'kind = "disk"\nper_pixel_rotation = true\nposition = [0.0, 4.0, 0.0]\nradius = 0.4\nnormal = [0.0, -1.0, 0.0]\nsamples = 32\ndistribution = "stratified"\n',
    "rect": 'kind = "rect"\nposition = [0.0, 4.0, 0.0]\nsize = [1.0, 0.5]\nnormal = [0.0, -1.0, 0.0]\ntangent = [1.0, 0.0, 0.0]\nsamples = 16\n',
    "rect_textured": 'kind = "rect"\nposition = [0.0, 4.0, 0.0]\nsize = [1.0, 0.5]\nnormal = [0.0, -1.0, 0.0]\nsamples = 16\ntexture = "glass.png"\n',
    "ellipsoid": 'kind = "ellipsoid"\nposition = [0.0, 4.0, 0.0]\nsemi_axes = [0.5, 0.2, 0.3]\nnormal = [0.0, -1.0, 0.0]\nsamples = 8\ndistribution = "uniform"\n',
    "explicit": 'kind = "explicit"\npositions = [[0.0, 4.0, 0.0], [0.1, 4.0, 0.0], [0.0, 4.0, 0.1]]\ncolor = [1.0, 0.5, 0.25]\nintensity = 2.0\n',
}
SHADOWS = '[shadows]\nlight_texels = 256\nsoft_light_texels = 128\nmode = "exact"\nlut_resolution = 64\n'
out("scene_toml", "minimal.toml", HEAD)
out("scene_toml", "full.toml", HEAD + "ground = { y = -1.0, half_size = 10.0 }\n" + CAMERA
    + "".join("[[light]]\n" + l for l in LIGHTS.values()) + SHADOWS)
for k, l in LIGHTS.items():
    out("scene_toml", f"light_{k}.toml", HEAD + CAMERA + "[[light]]\n" + l)
out("scene_toml", "nan.toml", HEAD + '[[light]]\nkind = "point"\nposition = [0.0, nan, inf]\n')
out("scene_toml", "file.toml", 'scene = "model.glb"\n' + CAMERA)

# --- scene_gltf -------------------------------------------------------------
for a in ["stairs.glb", "fence.glb", "plane_sphere.glb"]:
    with open(os.path.join(ROOT, "assets", a), "rb") as src:
        out("scene_gltf", a, src.read())


def png(w, h):
    """An RGBA PNG with a checkerboard alpha."""
    raw = b"".join(
        b"\0" + b"".join(bytes([(x * 60) % 256, (y * 60) % 256, 128, 255 if (x + y) % 2 else 0]) for x in range(w))
        for y in range(h))

    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xFFFFFFFF)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 6, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


class Doc:
    def __init__(self):
        self.j = {"asset": {"version": "2.0"}, "accessors": [], "bufferViews": [], "meshes": [], "nodes": []}
        self.bin = b""

    def view(self, data):
        self.bin += b"\0" * (-len(self.bin) % 4)
        self.j["bufferViews"].append({"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)})
        self.bin += data
        return len(self.j["bufferViews"]) - 1

    def acc(self, data, a):
        a["bufferView"] = self.view(data)
        self.j["accessors"].append(a)
        return len(self.j["accessors"]) - 1

    def pos(self, ps):
        data = b"".join(struct.pack("<3f", *p) for p in ps)
        lo = [min(p[i] for p in ps) for i in range(3)]
        hi = [max(p[i] for p in ps) for i in range(3)]
        return self.acc(data, {"componentType": 5126, "count": len(ps), "type": "VEC3", "min": lo, "max": hi})

    def idx(self, ix, ct=5123):
        fmt = {5121: "B", 5123: "H", 5125: "I"}[ct]
        return self.acc(struct.pack("<%d%s" % (len(ix), fmt), *ix), {"componentType": ct, "count": len(ix), "type": "SCALAR"})

    def gltf(self):
        j = dict(self.j)
        j["buffers"] = [{"byteLength": len(self.bin), "uri": "data:application/octet-stream;base64," + base64.b64encode(self.bin).decode()}]
        return json.dumps(j).encode()

    def glb(self):
        j = dict(self.j)
        j["buffers"] = [{"byteLength": len(self.bin)}]
        js = json.dumps(j).encode()
        js += b" " * (-len(js) % 4)
        b = self.bin + b"\0" * (-len(self.bin) % 4)
        body = struct.pack("<I4s", len(js), b"JSON") + js + struct.pack("<I4s", len(b), b"BIN\0") + b
        return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


QUAD = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]


def doc_indexed(ct, mode=4, ix=(0, 1, 2, 0, 2, 3)):
    d = Doc()
    p = d.pos(QUAD)
    i = d.idx(list(ix), ct)
    d.j["meshes"] = [{"name": "quad", "primitives": [{"attributes": {"POSITION": p}, "indices": i, "mode": mode}]}]
    d.j["nodes"] = [{"mesh": 0, "translation": [0, 1, 0], "rotation": [0, 0, 0.3826834, 0.9238795], "scale": [2, 2, 2]}]
    d.j["scenes"] = [{"nodes": [0]}]
    d.j["scene"] = 0
    return d


for ct in (5121, 5123, 5125):
    d = doc_indexed(ct)
    out("scene_gltf", f"indexed_{ct}.gltf", d.gltf())
    out("scene_gltf", f"indexed_{ct}.glb", d.glb())
out("scene_gltf", "strip.gltf", doc_indexed(5123, 5, (0, 1, 3, 2)).gltf())
out("scene_gltf", "fan.glb", doc_indexed(5123, 6, (0, 1, 2, 3)).glb())
out("scene_gltf", "lines.gltf", doc_indexed(5123, 1, (0, 1, 1, 2)).gltf())

# Hierarchy, matrix node, camera.
d = doc_indexed(5123)
d.j["nodes"] = [
    {"children": [1, 2], "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, -1, 0, 0.5, 0, 0, 1]},
    {"mesh": 0, "name": "child"},
    {"camera": 0, "translation": [0, 0, 4]},
]
d.j["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1, "aspectRatio": 1.5}}]
d.j["scenes"] = [{"nodes": [0]}]
out("scene_gltf", "hierarchy_camera.gltf", d.gltf())
out("scene_gltf", "hierarchy_camera.glb", d.glb())

# Sparse positions.
d = Doc()
base = d.pos(QUAD)
si = d.view(struct.pack("<2H", 1, 3))
sv = d.view(struct.pack("<6f", 2, 0, 0, 0, 2, 0))
d.j["accessors"][base]["sparse"] = {"count": 2, "indices": {"bufferView": si, "componentType": 5123}, "values": {"bufferView": sv}}
d.j["meshes"] = [{"primitives": [{"attributes": {"POSITION": base}}]}]
d.j["nodes"] = [{"mesh": 0}]
out("scene_gltf", "sparse.gltf", d.gltf())

# Quantized positions (KHR_mesh_quantization), normalized shorts.
d = Doc()
q = d.acc(struct.pack("<9h", 0, 0, 0, 32767, 0, 0, 0, 32767, 0) + b"\0\0",
          {"componentType": 5122, "normalized": True, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]})
d.j["meshes"] = [{"primitives": [{"attributes": {"POSITION": q}}]}]
d.j["nodes"] = [{"mesh": 0}]
d.j["extensionsUsed"] = ["KHR_mesh_quantization", "KHR_lights_punctual"]
d.j["extensionsRequired"] = ["KHR_mesh_quantization"]
out("scene_gltf", "quantized.gltf", d.gltf())

# Alpha-masked material with an embedded PNG base-colour texture and UVs.
d = doc_indexed(5123)
uv = d.acc(struct.pack("<8f", 0, 0, 1, 0, 1, 1, 0, 1), {"componentType": 5126, "count": 4, "type": "VEC2"})
img = d.view(png(4, 4))
d.j["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = uv
d.j["meshes"][0]["primitives"][0]["material"] = 0
d.j["images"] = [{"bufferView": img, "mimeType": "image/png"}]
d.j["textures"] = [{"source": 0}]
d.j["materials"] = [{"name": "leaf", "alphaMode": "MASK", "alphaCutoff": 0.4,
                     "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "baseColorFactor": [1, 1, 1, 0.8]}}]
out("scene_gltf", "textured.glb", d.glb())
out("scene_gltf", "textured.gltf", d.gltf())

# --- view_samples -----------------------------------------------------------
# The byte format of fuzz_targets/view_samples.rs.


def f(x):  # a small value: selector 2, then x * 16 as i8
    return bytes([2, int(round(x * 16)) & 0xFF])


def raw(x):  # selector 0, then the f64 bits
    return bytes([0]) + struct.pack("<d", x)


def v3(a, b, c):
    return f(a) + f(b) + f(c)


def u8(x):
    return bytes([x])


def u32(x):
    return struct.pack("<I", x)


def view_input(kind, shape, samples=16, mode=0):
    b = v3(0, 3, 4)  # eye
    b += u8(kind) + u8(2) + u32(samples) + v3(0, 4, 0) + shape
    b += u32(7) + f(1) + f(1) + f(1) + f(1)  # seed, colour, intensity
    b += u32(256) + u32(128) + u8(mode) + u32(32)  # settings
    b += u8(0)  # the scene unchanged
    n = 6
    b += u8(n)
    for i in range(n):
        b += u8(1) + v3(i * 0.25 - 0.6, 0, 0.1) + v3(0, 1, 0) + u8(0)
    return b


N, T = v3(0, -1, 0), v3(1, 0, 0)
out("view_samples", "point", view_input(0, b"", samples=1))
out("view_samples", "directional", view_input(1, v3(0.2, -1, 0.1), samples=1))
out("view_samples", "sphere", view_input(2, f(0.3)))
out("view_samples", "disk", view_input(3, f(0.3) + N + T, mode=1))
out("view_samples", "rect", view_input(4, f(0.5) + f(0.25) + N + T))
out("view_samples", "ellipsoid", view_input(5, v3(0.3, 0.2, 0.1) + N + T))
out("view_samples", "explicit", view_input(6, u8(3) + v3(0, 4, 0) + v3(0.1, 4, 0) + v3(0, 4, 0.1), samples=3))
out("view_samples", "far", view_input(0, b"", samples=1).replace(v3(0, 4, 0), raw(1e17) + f(4) + f(0), 1))
