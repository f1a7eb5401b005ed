"""Reads the render passes from an uncompressed (codec NONE) 32-bit float
OpenEXR file, such as Blender's OPEN_EXR_MULTILAYER output, without any
image library: Blender's own Python API gives no pixels of a multilayer
file's passes. OpenEXR layout: magic, version, header attributes (name,
type, size, value) up to an empty name (per part, then an empty header, in a
multi-part file), a table of scanline offsets (per part), then per scanline
(its part number in a multi-part file) its y, its byte count and each
channel's row (channels in alphabetical order)."""

import struct

import numpy as np

_FLOAT, _HALF, _UINT = 2, 1, 0
_BYTES = {_UINT: 4, _HALF: 2, _FLOAT: 4}


def _headers(data):
    """[(attributes, ...)] of each part, and the position after the headers."""
    if data[:4] != b"\x76\x2f\x31\x01":
        raise ValueError("not an OpenEXR file")
    version = struct.unpack_from("<I", data, 4)[0]
    if version & 0x200:
        raise ValueError("tiled OpenEXR files are not supported")
    multipart = bool(version & 0x1000)
    pos, headers = 8, []
    while True:
        attrs = {}
        while True:
            end = data.index(b"\0", pos)
            name = data[pos:end].decode()
            pos = end + 1
            if not name:
                break
            end = data.index(b"\0", pos)
            kind = data[pos:end].decode()
            size = struct.unpack_from("<i", data, end + 1)[0]
            attrs[name] = (kind, data[end + 5:end + 5 + size])
            pos = end + 5 + size
        if not attrs:  # the empty header after the last part
            break
        headers.append(attrs)
        if not multipart:
            break
    return headers, pos, multipart


def _channels(raw):
    out, pos = [], 0
    while raw[pos:pos + 1] != b"\0":
        end = raw.index(b"\0", pos)
        name = raw[pos:end].decode()
        pixel_type, _, xs, ys = struct.unpack_from("<iB3xii", raw, end + 1)
        if (xs, ys) != (1, 1):
            raise ValueError(f"channel {name} is subsampled")
        out.append((name, pixel_type))
        pos = end + 1 + 16
    return out


def read_passes(path):
    """{channel name: float32 (H, W)} with rows top to bottom, as in the file.
    Channels of a multi-part file (Blender 5.0: one part per pass) are named
    "<part name>.<channel>"."""
    with open(path, "rb") as f:
        data = f.read()
    headers, pos, multipart = _headers(data)
    parts = []
    for attrs in headers:
        if attrs["compression"][1][0] != 0:
            raise ValueError("only uncompressed OpenEXR is supported: set the codec to 'NONE'")
        x0, y0, x1, y1 = struct.unpack("<iiii", attrs["dataWindow"][1])
        prefix = attrs["name"][1].rstrip(b"\0").decode() + "." if multipart and "name" in attrs else ""
        channels = _channels(attrs["channels"][1])
        names = [(n if not prefix or n.startswith(prefix) else prefix + n, t) for n, t in channels]
        parts.append((x1 - x0 + 1, y1 - y0 + 1, y0, names))
    out = {}
    for width, height, _, names in parts:
        for name, _ in names:
            out[name] = np.empty((height, width), dtype=np.float32)
    for index, (width, height, y0, names) in enumerate(parts):
        offsets = np.frombuffer(data, dtype="<u8", count=height, offset=pos)
        pos += 8 * height
        for offset in offsets:
            p = int(offset) + (4 if multipart else 0)  # the part number
            y = struct.unpack_from("<i", data, p)[0] - y0
            p += 8  # y, byte count
            for name, pixel_type in names:
                dtype = {_FLOAT: "<f4", _HALF: "<f2", _UINT: "<u4"}[pixel_type]
                out[name][y] = np.frombuffer(data, dtype=dtype, count=width, offset=p).astype(np.float32)
                p += _BYTES[pixel_type] * width
    return out


def layer_passes(path, layer="ViewLayer"):
    """{pass name: float32 (H, W, channels)} of one view layer, rows top to
    bottom; channels in Blender's order (R, G, B, A / X, Y, Z / Z)."""
    order = {c: i for i, c in enumerate("RGBAXYZUVW")}
    grouped = {}
    for name, px in read_passes(path).items():
        parts = name.split(".")
        if len(parts) < 3 or parts[0] != layer:
            continue
        grouped.setdefault(".".join(parts[1:-1]), []).append((parts[-1], px))
    return {p: np.stack([px for _, px in sorted(chs, key=lambda c: order.get(c[0], 99))], axis=-1)
            for p, chs in grouped.items()}
