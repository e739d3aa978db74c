#!/usr/bin/env python3
"""Replays issue 69's attacks against a `tessera` binary and prints, for each, what it did.

    scripts/trust/probe.py --bin target/release/tessera

Every input is made here: a tar whose entry claims 64 GiB, an OpenEXR environment whose header
claims 60000x60000 pixels, an OBJ of one triangle 2,000 times, a recorded `auto` choice of
3,000,000 spp, a mesh that is a link out of its scene folder, a 16384x16384 frame, a second
coordinator with its own object store on the same job store, half-sent headers, and the job
store's file mode. A coordinator runs on loopback (SQLite, no workers) in a temporary
directory. It prints one line a probe, `refused`/`held` or what went wrong, and exits 1 if
any probe was not refused cleanly. Run it against an older build to see the defects.
"""

import argparse
import io
import json
import os
import socket
import stat
import struct
import subprocess
import sys
import tarfile
import tempfile
import time
import urllib.error
import urllib.request

TOKEN = "probe-client"
SCENE = {
    "units": "m",
    "camera": {"type": "pinhole", "position": [0.5, 0.5, -2], "look_at": [0.5, 0.5, 0], "fov_deg": 40},
    "film": {"width": 16, "height": 16},
    "integrator": {"type": "path", "spp": 1},
    "materials": {"white": {"type": "diffuse", "albedo": 0.5}},
    "lights": [{"type": "point", "position": [0.5, 0.5, -1], "intensity": 1}],
    "shapes": [{"type": "sphere", "center": [0.5, 0.5, 0], "radius": 0.3, "material": "white"}],
}


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def http(method, url, body=None, ctype="application/json"):
    req = urllib.request.Request(url, data=body, method=method)
    req.add_header("Authorization", f"Bearer {TOKEN}")
    if body is not None:
        req.add_header("Content-Type", ctype)
    try:
        with urllib.request.urlopen(req, timeout=120) as r:
            return r.status, r.read().decode(errors="replace")
    except urllib.error.HTTPError as e:
        return e.code, e.read().decode(errors="replace")
    except (urllib.error.URLError, ConnectionError, socket.timeout) as e:
        return None, str(e)


class Coordinator:
    def __init__(self, binary, data, objects=None):
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        args = [binary, "serve", "--listen", f"127.0.0.1:{self.port}", "--data", data,
                "--client-token", TOKEN, "--worker-token", "probe-worker"]
        if objects:
            args += ["--objects", objects]
        self.log = open(os.path.join(data + ".log"), "w")
        self.proc = subprocess.Popen(args, stdout=self.log, stderr=subprocess.STDOUT)
        for _ in range(200):
            if self.proc.poll() is not None:
                return
            if http("GET", self.url + "/healthz")[0] == 200:
                return
            time.sleep(0.05)

    def alive(self):
        return self.proc.poll() is None and http("GET", self.url + "/healthz")[0] == 200

    def stop(self):
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
        self.log.close()


def tar_of(files):
    out = io.BytesIO()
    with tarfile.open(fileobj=out, mode="w", format=tarfile.GNU_FORMAT) as t:
        for name, data in files.items():
            info = tarfile.TarInfo(name)
            info.size = len(data)
            t.addfile(info, io.BytesIO(data))
    return out.getvalue()


def lying_tar(claimed):
    info = tarfile.TarInfo("scene.json")
    info.size = claimed
    header = info.tobuf(format=tarfile.GNU_FORMAT)
    body = header + b"{" * 100
    return body + b"\0" * ((-len(body)) % 512) + b"\0" * 1024


def lying_exr(binary, work, side):
    """A 4x4 EXR rendered by the binary, its data window rewritten to claim side x side."""
    d = os.path.join(work, "exr")
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, "scene.json"), "w") as f:
        json.dump(SCENE, f)
    out = os.path.join(d, "small.exr")
    subprocess.run([binary, "render", os.path.join(d, "scene.json"), "--size", "4x4",
                    "--spp", "1", "-o", out], check=True, capture_output=True)
    data = bytearray(open(out, "rb").read())
    key = b"dataWindow\0box2i\0"
    at = data.index(key) + len(key) + 4
    data[at + 8:at + 16] = struct.pack("<ii", side - 1, side - 1)
    # The offset table after the header gets as many entries as the claimed lines need
    # (each pointing at the one real chunk), so the file is consistent but for its pixels.
    pos, attrs = 8, {}
    while data[pos] != 0:
        name_end = data.index(b"\0", pos)
        type_end = data.index(b"\0", name_end + 1)
        size = struct.unpack_from("<i", data, type_end + 1)[0]
        attrs[bytes(data[pos:name_end])] = (type_end + 5, bytes(data[type_end + 5:type_end + 5 + size]))
        pos = type_end + 5 + size
    header_end = pos + 1
    lines = {0: 1, 1: 1, 2: 1, 3: 16, 4: 32, 5: 16, 6: 32, 7: 32}[attrs[b"compression"][1][0]]
    old_chunks = -(-4 // lines)
    new_chunks = -(-side // lines)
    if b"chunkCount" in attrs:
        at = attrs[b"chunkCount"][0]
        data[at:at + 4] = struct.pack("<i", new_chunks)
    first = struct.unpack_from("<Q", data, header_end)[0]
    moved = first + 8 * (new_chunks - old_chunks)
    table = struct.pack("<Q", moved) * new_chunks
    return bytes(data[:header_end]) + table + bytes(data[header_end + 8 * old_chunks:])


def upload(c, files):
    status, body = http("POST", c.url + "/v1/bundles", tar_of(files), "application/x-tar")
    if status != 201:
        raise RuntimeError(f"upload: {status} {body}")
    return json.loads(body)["hash"]


def submit(c, bundle, settings):
    req = {"bundle": bundle, "scene": "scene.json", "settings": settings}
    return http("POST", c.url + "/v1/jobs", json.dumps(req).encode())


def verdict(name, ok, what):
    print(f"{'refused' if ok else 'DEFECT '}  {name}: {what}")
    return ok


def clean_error(code):
    """An exit with an error message: not success, a panic (101) or a signal (abort: 134)."""
    return code is not None and 0 < code < 100


def render(binary, scene_dir, timeout=600):
    r = subprocess.run([binary, "render", os.path.join(scene_dir, "scene.json"), "--spp", "1",
                        "--size", "16x16", "-o", os.path.join(scene_dir, "out.exr")],
                       capture_output=True, text=True, timeout=timeout)
    last = (r.stderr.strip().splitlines() or [""])[-1]
    return r.returncode, last


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bin", default="target/release/tessera")
    args = ap.parse_args()
    binary = os.path.abspath(args.bin)
    results = []
    with tempfile.TemporaryDirectory() as work:
        data = os.path.join(work, "data")
        c = Coordinator(binary, data)
        if not c.alive():
            print("the coordinator did not start; see", data + ".log")
            return 2
        def revive(c):
            """A coordinator that died on a probe is started again for the next one."""
            if c.alive():
                return c
            print("         (the coordinator died; starting it again)")
            c.stop()
            return Coordinator(binary, data)

        try:
            # 1. A tar header's claimed size.
            status, body = http("POST", c.url + "/v1/bundles", lying_tar(64 << 30), "application/x-tar")
            results.append(verdict("tar entry claiming 64 GiB (2 KB upload)",
                                   status == 400 and c.alive(), f"{status} {body[:150]}"))
            c = revive(c)
            status, body = http("POST", c.url + "/v1/bundles", b"", "application/x-tar")
            results.append(verdict("empty body as a bundle", status == 400, f"{status} {body[:120]}"))
            c = revive(c)
            # 2. An image header's claimed size, on the coordinator and in `tessera render`.
            exr = lying_exr(binary, work, 60000)
            scene = dict(SCENE, environment={"image": "sky.exr"})
            h = upload(c, {"scene.json": json.dumps(scene).encode(), "sky.exr": exr})
            status, body = submit(c, h, {})
            results.append(verdict(f"EXR of {len(exr)} bytes claiming 60000x60000 (submit)",
                                   status == 400 and c.alive(), f"{status} {body[:150]}"))
            d = os.path.join(work, "env")
            os.makedirs(d)
            open(os.path.join(d, "scene.json"), "w").write(json.dumps(scene))
            open(os.path.join(d, "sky.exr"), "wb").write(exr)
            code, last = render(binary, d)
            results.append(verdict("EXR claiming 60000x60000 (tessera render)", clean_error(code),
                                   f"exit {code}: {last[:150]}"))
            c = revive(c)
            # 3. One triangle 2,000 times.
            d = os.path.join(work, "copies")
            os.makedirs(d)
            open(os.path.join(d, "tri.obj"), "w").write("v 0 0 0\nv 1 0 0\nv 0 1 0\n" + "f 1 2 3\n" * 2000)
            s = dict(SCENE, shapes=[{"type": "mesh", "file": "tri.obj", "material": "white"}])
            open(os.path.join(d, "scene.json"), "w").write(json.dumps(s))
            code, last = render(binary, d)
            results.append(verdict("OBJ of one triangle 2,000 times (tessera render)", code == 0, f"exit {code} {last[:150]}"))
            c = revive(c)
            # 4. A recorded choice past the limits.
            h = upload(c, {"scene.json": json.dumps(SCENE).encode()})
            c = revive(c)
            for what, choice in [("spp 3,000,000", {"method": "path", "spp": 3000000, "report": []}),
                                 ("photons 4294967295", {"method": "photon", "spp": 4, "photons": 4294967295, "report": []})]:
                status, body = submit(c, h, {"integrator": "auto", "choice": choice})
                results.append(verdict(f"settings.choice {what}", status == 400, f"{status} {body[:150]}"))
            c = revive(c)
            # 5. A link out of the scene folder.
            d = os.path.join(work, "leak")
            os.makedirs(d)
            secret = os.path.join(work, "secret.obj")
            open(secret, "w").write("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
            os.symlink(secret, os.path.join(d, "leak.obj"))
            s = dict(SCENE, shapes=[{"type": "mesh", "file": "leak.obj", "material": "white"}])
            open(os.path.join(d, "scene.json"), "w").write(json.dumps(s))
            code, last = render(binary, d)
            results.append(verdict("mesh linked from outside the scene folder (tessera render)", clean_error(code),
                                   f"exit {code}: {last[:150]}"))
            c = revive(c)
            # 7. A frame too large to fold.
            status, body = submit(c, h, {"size": [16384, 16384]})
            results.append(verdict("a 16384x16384 frame", status == 400, f"{status} {body[:200]}"))
            c = revive(c)
            # 9. Half-sent headers; the job store's mode.
            s = socket.create_connection(("127.0.0.1", c.port))
            s.sendall(b"GET /healthz HTTP/1.1\r\nHost: x\r\n")
            s.settimeout(60)
            start = time.time()
            try:
                s.recv(1)
            except socket.timeout:
                pass
            held = time.time() - start
            s.close()
            results.append(verdict("half-sent headers", held < 20, f"connection held {held:.1f} s"))
            mode = stat.S_IMODE(os.stat(os.path.join(data, "tessera.db")).st_mode)
            results.append(verdict("tessera.db mode", mode & 0o077 == 0, oct(mode)))
        finally:
            c.stop()
        # 8. A second coordinator of the same job store with its own object store.
        other = Coordinator(binary, data, objects=os.path.join(work, "other-objects"))
        started = other.alive()
        other.stop()
        results.append(verdict("a coordinator with another object store on the same job store",
                               not started, "started" if started else "refused to start"))
    print(f"{sum(results)} refused, {len(results) - sum(results)} defects")
    return 0 if all(results) else 1


if __name__ == "__main__":
    sys.exit(main())
