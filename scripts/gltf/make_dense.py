"""Writes a glTF 2.0 binary (.glb) of a dense displaced grid — a terrain of about N
triangles with vertex normals — under a sun (KHR_lights_punctual directional) and a point
light, seen by a perspective camera: the production-size geometry for `tessera bench load`.
With `--textures SIDE` the ground also gets texture coordinates and three external PNG
textures of SIDE × SIDE RGB texels beside the file (base colour, metallic-roughness, normal
map), filled with noise so that they compress no better than photographs: production-size
textures. Python's standard library only.

    python3 scripts/gltf/make_dense.py /tmp/dense.glb --triangles 2000000
    python3 scripts/gltf/make_dense.py /tmp/big/dense.glb --triangles 2000000 --textures 4096
"""

import argparse
import array
import json
import math
import os
import struct
import zlib


def write_png(path, side, row):
    """An 8-bit RGB PNG of `side` rows, row j's bytes from `row(j)`."""
    raw = bytearray()
    for j in range(side):
        raw += b"\0"  # filter: none
        raw += row(j)

    def chunk(kind, data):
        c = struct.pack(">I", len(data)) + kind + data
        return c + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n")
        f.write(chunk(b"IHDR", struct.pack(">IIBBBBB", side, side, 8, 2, 0, 0, 0)))
        f.write(chunk(b"IDAT", zlib.compress(bytes(raw), 6)))
        f.write(chunk(b"IEND", b""))
    return os.path.getsize(path)


def textures(folder, side):
    """Base colour (earthy noise), metallic-roughness (rough, non-metal) and a normal map
    (small random tilts), each SIDE × SIDE; returns their file names and total bytes."""
    earth = bytes(60 + (b * 140) // 255 for b in range(256))
    rough = bytes(150 + (b % 100) for b in range(256))
    tilt = bytes(112 + (b & 31) for b in range(256))

    def base(_):
        return os.urandom(side * 3).translate(earth)

    def mr(_):
        r = bytearray(os.urandom(side * 3).translate(rough))
        r[0::3] = bytes(side)  # R unused
        r[2::3] = bytes(side)  # B: metal 0
        return bytes(r)

    def normal(_):
        r = bytearray(os.urandom(side * 3).translate(tilt))
        r[2::3] = b"\xff" * side  # z up
        return bytes(r)

    names = ["dense_base.png", "dense_mr.png", "dense_normal.png"]
    total = sum(write_png(os.path.join(folder, n), side, f) for n, f in zip(names, [base, mr, normal]))
    return names, total


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--triangles", type=int, default=2_000_000)
    ap.add_argument("--textures", type=int, default=0, help="texture side in texels (0: none)")
    a = ap.parse_args()
    n = max(2, int(math.sqrt(a.triangles / 2)))  # cells per side
    size = 20.0

    def height(x, z):
        return 0.6 * math.sin(x * 0.9) * math.cos(z * 0.7) + 0.15 * math.sin(x * 5.1 + z * 3.7)

    pos = array.array("f")
    nor = array.array("f")
    uv = array.array("f")
    repeat = 4.0  # the textures tile 4 × 4 times across the ground
    h = size / n
    for j in range(n + 1):
        z = -size / 2 + j * h
        for i in range(n + 1):
            x = -size / 2 + i * h
            y = height(x, z)
            pos.extend((x, y, z))
            dx = (height(x + 1e-3, z) - height(x - 1e-3, z)) / 2e-3
            dz = (height(x, z + 1e-3) - height(x, z - 1e-3)) / 2e-3
            l = math.sqrt(dx * dx + 1 + dz * dz)
            nor.extend((-dx / l, 1 / l, -dz / l))
            uv.extend((i / n * repeat, j / n * repeat))
    idx = array.array("I")
    for j in range(n):
        for i in range(n):
            a0 = j * (n + 1) + i
            b0 = a0 + 1
            c0 = a0 + n + 1
            d0 = c0 + 1
            idx.extend((a0, c0, b0, b0, c0, d0))
    blobs = [pos.tobytes(), nor.tobytes(), idx.tobytes()]
    if a.textures:
        blobs.append(uv.tobytes())
    offsets, off = [], 0
    for b in blobs:
        offsets.append(off)
        off += len(b)
    binary = b"".join(blobs)
    verts = (n + 1) * (n + 1)
    lo = [min(pos[0::3]), min(pos[1::3]), min(pos[2::3])]
    hi = [max(pos[0::3]), max(pos[1::3]), max(pos[2::3])]
    doc = {
        "asset": {"version": "2.0", "generator": "tessera scripts/gltf/make_dense.py"},
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "directional", "intensity": 3.0, "color": [1.0, 0.95, 0.9]},
            {"type": "point", "intensity": 4000.0},
        ]}},
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 2, 3]}],
        "nodes": [
            {"mesh": 0, "name": "Terrain"},
            {"camera": 0, "translation": [0.0, 6.0, 14.0],
             "rotation": [-0.2164396, 0.0, 0.0, 0.976296]},
            {"rotation": [-0.5, 0.3, 0.1, 0.8], "extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"translation": [2.0, 3.0, 2.0], "extensions": {"KHR_lights_punctual": {"light": 1}}},
        ],
        "cameras": [{"type": "perspective",
                     "perspective": {"yfov": 0.8, "aspectRatio": 16 / 9, "znear": 0.1}}],
        "meshes": [{"name": "Terrain", "primitives": [{
            "attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2, "material": 0}]}],
        "materials": [{"name": "Ground", "pbrMetallicRoughness": {
            "baseColorFactor": [0.45, 0.4, 0.3, 1.0], "metallicFactor": 0.0,
            "roughnessFactor": 0.7}}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": verts, "type": "VEC3",
             "min": lo, "max": hi},
            {"bufferView": 1, "componentType": 5126, "count": verts, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5125, "count": len(idx), "type": "SCALAR"},
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": offsets[k], "byteLength": len(blobs[k])}
            for k in range(3)
        ],
        "buffers": [{"byteLength": len(binary)}],
    }
    if a.textures:
        folder = os.path.dirname(os.path.abspath(a.out))
        names, tex_bytes = textures(folder, a.textures)
        doc["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = 3
        doc["accessors"].append(
            {"bufferView": 3, "componentType": 5126, "count": verts, "type": "VEC2"})
        doc["bufferViews"] = [
            {"buffer": 0, "byteOffset": offsets[k], "byteLength": len(blobs[k])}
            for k in range(4)
        ]
        doc["images"] = [{"uri": n} for n in names]
        doc["samplers"] = [{"wrapS": 10497, "wrapT": 10497}]
        doc["textures"] = [{"source": k, "sampler": 0} for k in range(3)]
        pbr = doc["materials"][0]["pbrMetallicRoughness"]
        pbr["baseColorFactor"] = [1.0, 1.0, 1.0, 1.0]
        pbr["roughnessFactor"] = 1.0
        pbr["baseColorTexture"] = {"index": 0}
        pbr["metallicRoughnessTexture"] = {"index": 1}
        doc["materials"][0]["normalTexture"] = {"index": 2}
        print(f"{len(names)} textures of {a.textures}² texels: {tex_bytes / 2**20:.1f} MiB of PNG")
    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    binary += b"\0" * (-len(binary) % 4)
    total = 12 + 8 + len(js) + 8 + len(binary)
    with open(a.out, "wb") as f:
        f.write(struct.pack("<4sII", b"glTF", 2, total))
        f.write(struct.pack("<I4s", len(js), b"JSON"))
        f.write(js)
        f.write(struct.pack("<I4s", len(binary), b"BIN\0"))
        f.write(binary)
    print(f"{a.out}: {len(idx) // 3} triangles, {verts} vertices, {total / 2**20:.1f} MiB")


if __name__ == "__main__":
    main()
