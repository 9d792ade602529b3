"""Small file readers and writers for the synthetic-capture scripts, in numpy only.

Blender's bundled Python has numpy but not the hairrecon module, so the renderer reads and writes
its files here:

- Cem Yuksel's ``.hair`` strands (read and write);
- PNG (write: 8- or 16-bit, grey, RGB or RGBA; read: the same, non-interlaced, for the tests);
- OpenEXR scanline images with float32 channels (write: uncompressed; read: uncompressed, ZIPS and
  ZIP compression, which covers what Blender writes with ``exr_codec`` NONE/ZIP/ZIPS);
- PLY triangle meshes (read: ASCII and binary little/big endian; write: binary little endian);
- hairrecon's oriented points (``points3d.ply``, ``points_directed.ply``: read);
- strands resampled by arc length.

Nothing here imports bpy, so the tests use it too.
"""

from __future__ import annotations

import os
import struct
import zlib
from pathlib import Path

import numpy as np


def _write_atomic(path, data: bytes) -> None:
    """Writes through a temporary file in the same folder and renames it, so that an interrupted run
    never leaves a half-written file under the final name."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)

# ---------------------------------------------------------------------------------------------
# .hair (Cem Yuksel): 128-byte header, then optional arrays in a fixed order.
# ---------------------------------------------------------------------------------------------

_HAIR_SEGMENTS, _HAIR_POINTS, _HAIR_THICKNESS, _HAIR_TRANSPARENCY, _HAIR_COLOR = 1, 2, 4, 8, 16


def read_hair(path) -> tuple[np.ndarray, np.ndarray]:
    """Returns (points float32 (P, 3), counts int64 (S,)) of a .hair file: points per strand."""
    data = Path(path).read_bytes()
    if len(data) < 128 or data[:4] != b"HAIR":
        raise ValueError(f"{path}: not a .hair file (no HAIR signature)")
    n_strands, n_points, flags, d_segments = struct.unpack_from("<4I", data, 4)
    off = 128
    if flags & _HAIR_SEGMENTS:
        segs = np.frombuffer(data, "<u2", n_strands, off).astype(np.int64)
        off += 2 * n_strands
    else:
        segs = np.full(n_strands, d_segments, np.int64)
    if not flags & _HAIR_POINTS:
        raise ValueError(f"{path}: the .hair file has no points array")
    counts = segs + 1
    if int(counts.sum()) != n_points:
        raise ValueError(f"{path}: segment counts add up to {int(counts.sum())} points, header says {n_points}")
    if off + 12 * n_points > len(data):
        raise ValueError(f"{path}: truncated points array")
    pts = np.frombuffer(data, "<f4", 3 * n_points, off).reshape(-1, 3).astype(np.float32)
    return pts, counts


def write_hair(path, points: np.ndarray, counts: np.ndarray, info: str = "hairrecon") -> None:
    """Writes strands as .hair with a segments array and points only (no thickness/colour)."""
    points = np.ascontiguousarray(points, dtype="<f4").reshape(-1, 3)
    counts = np.asarray(counts, dtype=np.int64)
    if counts.min(initial=2) < 2 or counts.max(initial=2) > 65536 or counts.sum() != len(points):
        raise ValueError("every strand needs 2..65536 points and the counts must add up to the point count")
    head = b"HAIR" + struct.pack("<4I", len(counts), len(points), _HAIR_SEGMENTS | _HAIR_POINTS, 0)
    head += struct.pack("<2f3f", 1.0, 0.0, 0.0, 0.0, 0.0)
    head += info.encode("ascii", "replace")[:88].ljust(88, b"\0")
    assert len(head) == 128
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    _write_atomic(path, head + (counts - 1).astype("<u2").tobytes() + points.tobytes())


def strand_offsets(counts: np.ndarray) -> np.ndarray:
    """Start index of each strand in the flat points array (length S + 1)."""
    return np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)


def strand_tangents(points: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Unit tangents per point (central differences inside a strand, one-sided at its ends)."""
    off = strand_offsets(counts)
    nxt = np.arange(len(points)) + 1
    prv = np.arange(len(points)) - 1
    last = off[1:] - 1
    first = off[:-1]
    nxt[last] = last
    prv[first] = first
    d = points[nxt] - points[prv]
    n = np.linalg.norm(d, axis=1, keepdims=True)
    return d / np.maximum(n, 1e-12)


def resample_by_arc(strand: np.ndarray, step: float) -> tuple[np.ndarray, float]:
    """One strand's points every ``step`` of arc from the root (linear between its points), and its
    arc length; no samples when the strand has fewer than two points."""
    if len(strand) < 2:
        return np.zeros((0, 3)), 0.0
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(strand, axis=0), axis=1))])
    t = np.arange(0.0, arc[-1], step)
    return np.stack([np.interp(t, arc, strand[:, k]) for k in range(3)], axis=1), float(arc[-1])


# ---------------------------------------------------------------------------------------------
# PNG
# ---------------------------------------------------------------------------------------------


def _png_chunk(tag: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)


def write_png(path, img: np.ndarray) -> None:
    """Writes a uint8 or uint16 array (H, W), (H, W, 3) or (H, W, 4) as PNG."""
    img = np.asarray(img)
    if img.dtype not in (np.uint8, np.uint16):
        raise TypeError("write_png wants uint8 or uint16 pixels")
    if img.ndim == 2:
        img = img[:, :, None]
    h, w, c = img.shape
    colour = {1: 0, 2: 4, 3: 2, 4: 6}[c]
    depth = 8 if img.dtype == np.uint8 else 16
    rows = img.astype(">u2" if depth == 16 else np.uint8).reshape(h, -1).view(np.uint8).reshape(h, -1)
    raw = np.concatenate([np.zeros((h, 1), np.uint8), rows], axis=1).tobytes()
    out = b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", struct.pack(">2I5B", w, h, depth, colour, 0, 0, 0))
    out += _png_chunk(b"IDAT", zlib.compress(raw, 6)) + _png_chunk(b"IEND", b"")
    _write_atomic(path, out)


def read_png(path) -> np.ndarray:
    """Reads a non-interlaced 8/16-bit grey/grey+alpha/RGB/RGBA PNG as (H, W, C) uint8/uint16."""
    data = Path(path).read_bytes()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"{path}: not a PNG file")
    pos, idat, ihdr = 8, [], None
    while pos < len(data):
        (n,) = struct.unpack_from(">I", data, pos)
        tag = data[pos + 4 : pos + 8]
        body = data[pos + 8 : pos + 8 + n]
        pos += 12 + n
        if tag == b"IHDR":
            ihdr = struct.unpack(">2I5B", body)
        elif tag == b"IDAT":
            idat.append(body)
        elif tag == b"IEND":
            break
    w, h, depth, colour, _, _, interlace = ihdr
    if interlace or depth not in (8, 16) or colour not in (0, 2, 4, 6):
        raise ValueError(f"{path}: unsupported PNG (depth {depth}, colour type {colour}, interlace {interlace})")
    c = {0: 1, 2: 3, 4: 2, 6: 4}[colour]
    bpp = c * depth // 8
    raw = np.frombuffer(zlib.decompress(b"".join(idat)), np.uint8).reshape(h, 1 + w * bpp)
    out = np.zeros((h, w * bpp), np.int32)
    prev = np.zeros(w * bpp, np.int32)
    for y in range(h):
        f, line = raw[y, 0], raw[y, 1:].astype(np.int32)
        if f == 0:
            cur = line
        elif f == 2:
            cur = (line + prev) & 255
        else:
            cur = np.zeros_like(line)
            for x in range(w * bpp):
                a = cur[x - bpp] if x >= bpp else 0
                b = prev[x]
                cc = prev[x - bpp] if x >= bpp else 0
                if f == 1:
                    p = a
                elif f == 3:
                    p = (a + b) // 2
                else:
                    pa, pb, pc = abs(b - cc), abs(a - cc), abs(a + b - 2 * cc)
                    p = a if pa <= pb and pa <= pc else (b if pb <= pc else cc)
                cur[x] = (line[x] + p) & 255
        out[y] = cur
        prev = cur
    px = out.astype(np.uint8)
    if depth == 16:
        px = px.reshape(h, -1, 2)
        return (px[:, :, 0].astype(np.uint16) << 8 | px[:, :, 1]).reshape(h, w, c)
    return px.reshape(h, w, c)


def linear_to_srgb8(rgb: np.ndarray) -> np.ndarray:
    """Scene-linear float RGB to 8-bit sRGB (Blender's "Standard" view transform), clipped."""
    x = np.clip(rgb, 0.0, 1.0)
    s = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.round(s * 255.0).astype(np.uint8)


# ---------------------------------------------------------------------------------------------
# OpenEXR (scanline, float32/half channels)
# ---------------------------------------------------------------------------------------------

_EXR_MAGIC = 20000630


def write_exr(path, channels: dict[str, np.ndarray]) -> None:
    """Writes float32 channels of one size as an uncompressed scanline EXR (one line per block)."""
    names = sorted(channels)
    arrs = [np.ascontiguousarray(channels[n], dtype="<f4") for n in names]
    h, w = arrs[0].shape
    chlist = b"".join(n.encode() + b"\0" + struct.pack("<i4B2i", 2, 0, 0, 0, 0, 1, 1) for n in names) + b"\0"

    def attr(name, typ, data):
        return name.encode() + b"\0" + typ.encode() + b"\0" + struct.pack("<i", len(data)) + data

    box = struct.pack("<4i", 0, 0, w - 1, h - 1)
    header = struct.pack("<ii", _EXR_MAGIC, 2)
    header += attr("channels", "chlist", chlist)
    header += attr("compression", "compression", b"\0")
    header += attr("dataWindow", "box2i", box)
    header += attr("displayWindow", "box2i", box)
    header += attr("lineOrder", "lineOrder", b"\0")
    header += attr("pixelAspectRatio", "float", struct.pack("<f", 1.0))
    header += attr("screenWindowCenter", "v2f", struct.pack("<2f", 0.0, 0.0))
    header += attr("screenWindowWidth", "float", struct.pack("<f", 1.0))
    header += b"\0"
    line_bytes = 4 * w * len(names)
    table_end = len(header) + 8 * h
    offsets = table_end + np.arange(h, dtype=np.int64) * (8 + line_bytes)
    stacked = np.stack(arrs, axis=1)  # (h, C, w)
    body = bytearray()
    for y in range(h):
        body += struct.pack("<ii", y, line_bytes) + stacked[y].tobytes()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    _write_atomic(path, header + offsets.astype("<u8").tobytes() + bytes(body))


def _exr_unzip(block: bytes, expected: int) -> bytes:
    raw = np.frombuffer(zlib.decompress(block), np.uint8)
    if len(raw) != expected:
        raise ValueError("EXR: bad ZIP block size")
    t = raw.astype(np.int32)
    t = np.cumsum(np.concatenate([[t[0]], t[1:] - 128])) & 255  # undo the delta predictor
    t = t.astype(np.uint8)
    half = (len(t) + 1) // 2
    out = np.empty_like(t)
    out[0::2] = t[:half]
    out[1::2] = t[half:]
    return out.tobytes()


def read_exr(path) -> dict[str, np.ndarray]:
    """Reads a scanline EXR, single- or multi-part (Blender's multilayer files are multi-part), with
    NONE, ZIPS or ZIP compression, as {channel name: float32 (H, W)} over all parts."""
    data = Path(path).read_bytes()
    magic, ver = struct.unpack_from("<ii", data, 0)
    if magic != _EXR_MAGIC:
        raise ValueError(f"{path}: not an OpenEXR file")
    if ver & 0x200 or ver & 0x800:
        raise ValueError(f"{path}: tiled or deep EXR is not supported here")
    multipart = bool(ver & 0x1000)
    pos, headers = 8, []
    while True:
        attrs = {}
        while data[pos] != 0:
            e = data.index(b"\0", pos)
            name = data[pos:e].decode()
            e2 = data.index(b"\0", e + 1)
            (size,) = struct.unpack_from("<i", data, e2 + 1)
            attrs[name] = data[e2 + 5 : e2 + 5 + size]
            pos = e2 + 5 + size
        pos += 1
        headers.append(attrs)
        if not multipart or data[pos] == 0:
            break
    if multipart:
        pos += 1
    parts = []
    for attrs in headers:
        chans, cl, p = [], attrs["channels"], 0
        while cl[p] != 0:
            e = cl.index(b"\0", p)
            (ptype,) = struct.unpack_from("<i", cl, e + 1)
            chans.append((cl[p:e].decode(), ptype))
            p = e + 17
        comp = attrs["compression"][0]
        x0, y0, x1, y1 = struct.unpack("<4i", attrs["dataWindow"])
        lpb = {0: 1, 2: 1, 3: 16}.get(comp)
        if lpb is None:
            raise ValueError(f"{path}: EXR compression {comp} is not supported (use NONE, ZIPS or ZIP)")
        nblocks = (y1 - y0 + lpb) // lpb
        parts.append((chans, comp, (x0, y0, x1, y1), lpb, np.frombuffer(data, "<u8", nblocks, pos)))
        pos += 8 * nblocks
    dtypes = {0: "<u4", 1: "<f2", 2: "<f4"}  # uint, half, float
    out = {}
    for chans, comp, (x0, y0, x1, y1), lpb, offsets in parts:
        w, h = x1 - x0 + 1, y1 - y0 + 1
        res = {n: np.zeros((h, w), np.float32) for n, _ in chans}
        for o in offsets:
            o = int(o) + (4 if multipart else 0)
            y, n = struct.unpack_from("<ii", data, o)
            block = data[o + 8 : o + 8 + n]
            nl = min(lpb, y1 - y + 1)
            expected = nl * w * sum(2 if t == 1 else 4 for _, t in chans)
            if comp != 0 and n < expected:
                block = _exr_unzip(block, expected)
            q = 0
            for line in range(nl):
                for name, t in chans:
                    res[name][y - y0 + line] = np.frombuffer(block, dtypes[t], w, q).astype(np.float32)
                    q += w * (2 if t == 1 else 4)
        out.update(res)
    return out


# ---------------------------------------------------------------------------------------------
# PLY triangle meshes
# ---------------------------------------------------------------------------------------------

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}  # fmt: skip


def read_ply(path) -> tuple[np.ndarray, np.ndarray]:
    """Reads a PLY triangle mesh as (vertices float64 (V, 3), triangles int64 (F, 3)).

    Polygons with more than three corners are fanned into triangles."""
    data = Path(path).read_bytes()
    end = data.index(b"end_header")
    end = data.index(b"\n", end) + 1
    lines = data[:end].decode("ascii", "replace").splitlines()
    fmt, elements = None, []
    for ln in lines:
        tok = ln.split()
        if not tok:
            continue
        if tok[0] == "format":
            fmt = tok[1]
        elif tok[0] == "element":
            elements.append([tok[1], int(tok[2]), []])
        elif tok[0] == "property":
            elements[-1][2].append(tok[1:])
    verts, faces = None, []
    if fmt == "ascii":
        words = data[end:].split()
        p = 0
        for name, n, props in elements:
            if name == "vertex":
                k = len(props)
                arr = np.array(words[p : p + n * k], dtype=np.float64).reshape(n, k)
                names = [pr[-1] for pr in props]
                verts = arr[:, [names.index(a) for a in "xyz"]]
                p += n * k
            else:
                for _ in range(n):
                    for pr in props:
                        if pr[0] == "list":
                            m = int(words[p])
                            if name == "face":
                                faces.append([int(x) for x in words[p + 1 : p + 1 + m]])
                            p += 1 + m
                        else:
                            p += 1
    else:
        bo = "<" if fmt == "binary_little_endian" else ">"
        p = end
        for name, n, props in elements:
            if all(pr[0] != "list" for pr in props):
                dt = np.dtype([(pr[-1], bo + _PLY_TYPES[pr[0]]) for pr in props])
                arr = np.frombuffer(data, dt, n, p)
                p += n * dt.itemsize
                if name == "vertex":
                    verts = np.stack([arr[a].astype(np.float64) for a in "xyz"], axis=1)
                continue
            if name == "face" and len(props) == 1:
                ct = np.dtype(bo + _PLY_TYPES[props[0][1]])
                it = np.dtype(bo + _PLY_TYPES[props[0][2]])
                first = np.frombuffer(data, ct, 1, p)[0] if n else 3
                dt = np.dtype([("n", ct), ("i", it, (int(first),))])
                arr = np.frombuffer(data, dt, n, p) if n and p + n * dt.itemsize <= len(data) else None
                if arr is not None and np.all(arr["n"] == first):
                    faces = arr["i"].astype(np.int64)
                    p += n * dt.itemsize
                    continue
            for _ in range(n):  # general (slow) path: mixed polygon sizes or extra properties
                for pr in props:
                    if pr[0] == "list":
                        ct = np.dtype(bo + _PLY_TYPES[pr[1]])
                        it = np.dtype(bo + _PLY_TYPES[pr[2]])
                        m = int(np.frombuffer(data, ct, 1, p)[0])
                        p += ct.itemsize
                        idx = np.frombuffer(data, it, m, p)
                        p += m * it.itemsize
                        if name == "face":
                            faces.append(list(idx))
                    else:
                        p += np.dtype(_PLY_TYPES[pr[0]]).itemsize
    if verts is None:
        raise ValueError(f"{path}: PLY has no vertex element")
    if isinstance(faces, np.ndarray):
        tris = faces.reshape(-1, faces.shape[1]) if len(faces) else np.zeros((0, 3), np.int64)
        if tris.shape[1] > 3:
            tris = np.concatenate([tris[:, [0, k, k + 1]] for k in range(1, tris.shape[1] - 1)])
    else:
        tris = [[f[0], f[k], f[k + 1]] for f in faces for k in range(1, len(f) - 1)]
        tris = np.array(tris, np.int64).reshape(-1, 3)
    return verts, tris.astype(np.int64)


def read_oriented_points(path) -> tuple[np.ndarray, np.ndarray]:
    """hairrecon's oriented 3D points (binary little-endian PLY with float x y z nx ny nz
    confidence) as (positions float64 (N, 3), unit directions float64 (N, 3))."""
    data = Path(path).read_bytes()
    try:
        end = data.index(b"end_header\n") + len(b"end_header\n")
    except ValueError:
        raise ValueError(f"{path}: no end_header; expected hairrecon's oriented points (binary PLY)") from None
    lines = data[:end].decode("ascii", "replace").splitlines()
    props = [ln.split()[1:] for ln in lines if ln.startswith("property")]
    want = [["float", a] for a in ("x", "y", "z", "nx", "ny", "nz", "confidence")]
    if "format binary_little_endian 1.0" not in lines or props != want:
        raise ValueError(
            f"{path}: expected hairrecon's oriented points (binary little-endian x y z nx ny nz confidence)"
        )
    n = int(next(ln for ln in lines if ln.startswith("element vertex")).split()[2])
    a = np.frombuffer(data, "<f4", n * 7, end).reshape(n, 7)
    return a[:, :3].astype(np.float64), a[:, 3:6].astype(np.float64)


def write_ply(path, vertices: np.ndarray, triangles: np.ndarray) -> None:
    """Writes a binary little-endian PLY with float x, y, z and uint triangle indices."""
    v = np.ascontiguousarray(vertices, dtype="<f4").reshape(-1, 3)
    f = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    head = (
        "ply\nformat binary_little_endian 1.0\ncomment written by hairrecon scripts/_hairio.py\n"
        f"element vertex {len(v)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(f)}\nproperty list uchar uint vertex_indices\nend_header\n"
    )
    dt = np.dtype([("n", "u1"), ("i", "<u4", (3,))])
    fa = np.empty(len(f), dt)
    fa["n"] = 3
    fa["i"] = f
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    _write_atomic(path, head.encode() + v.tobytes() + fa.tobytes())
