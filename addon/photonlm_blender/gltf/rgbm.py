"""A lightmap in an 8-bit PNG: RGBM (no bpy, so it runs in plain Python too).

A texel's value (R, G, B) in the lightmap's units is stored as 8-bit (r, g, b, m) with

    value = (r, g, b) * m * RANGE     (r, g, b, m read as numbers in [0, 1]; linear, no sRGB curve)

where RANGE is the lightmap's brightest channel value (declared with the file). m is the texel's
largest channel over RANGE, rounded up to the next 1/255; r, g and b are rounded to the nearest
1/255. Decoding is one multiply in any shader, and every viewer reads PNG.

Error: a channel is off by at most half a step of r, g, b: |decoded - value| <= m RANGE / 510.
For a texel whose largest channel c is at least RANGE / 255 (m >= 2/255 then, and c > m RANGE / 2)
that is at most 1/255 = 0.39 % of c; darker texels are off by at most RANGE / 130050.
"""
import struct
import zlib

import numpy as np

ENCODING = "RGBM"
STEPS = 255.0


def lightmap_range(rgb):
    """RANGE for a lightmap: its largest finite channel value (1 for a black lightmap)."""
    finite = rgb[np.isfinite(rgb)]
    top = float(finite.max()) if finite.size else 0.0
    return top if top > 0.0 else 1.0


def encode(rgb, value_range):
    """(h, w, 3) float values -> (h, w, 4) uint8 RGBM for `value_range` (see the module text).
    Negative and non-finite values count as 0; values above the range are clipped to it."""
    x = np.nan_to_num(np.asarray(rgb, np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    x = np.clip(x / value_range, 0.0, 1.0)
    peak = x.max(axis=2)
    m = np.ceil(peak * STEPS)                       # 0 .. 255; 0 only for a black texel
    scale = np.where(m > 0, STEPS / np.maximum(m, 1.0), 0.0)
    c = np.clip(np.rint(x * scale[..., None] * STEPS), 0, 255)
    return np.concatenate([c, m[..., None]], axis=2).astype(np.uint8)


def decode(rgbm, value_range):
    """(h, w, 4) uint8 (or floats in [0, 1]) RGBM -> (h, w, 3) float64 values."""
    v = np.asarray(rgbm, np.float64)
    if np.asarray(rgbm).dtype == np.uint8:
        v = v / STEPS
    return v[..., :3] * v[..., 3:4] * value_range


def error_bound(rgbm, value_range):
    """Per texel, the largest |decoded - value| encode() allows: m RANGE / 510."""
    return np.asarray(rgbm, np.float64)[..., 3] / STEPS * value_range / (2.0 * STEPS)


SIGNED = "RGBM_SIGNED"


def signed_range(values):
    """RANGE for signed values (SH L1 bands): their largest finite magnitude (1 for all zeros)."""
    finite = np.abs(values[np.isfinite(values)])
    top = float(finite.max()) if finite.size else 0.0
    return top if top > 0.0 else 1.0


def encode_signed(values, value_range):
    """(h, w, 3) signed values -> (h, w, 4) uint8 for `value_range`: value = (2 (r, g, b) - 1) m RANGE,
    m the texel's largest magnitude over RANGE rounded up to 1/255, r, g, b rounded to 1/255; a channel
    is off by at most m RANGE / 255. Non-finite values count as 0."""
    x = np.nan_to_num(np.asarray(values, np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    x = np.clip(x / value_range, -1.0, 1.0)
    m = np.ceil(np.abs(x).max(axis=2) * STEPS)
    scale = np.where(m > 0, STEPS / np.maximum(m, 1.0), 0.0)
    c = np.clip(np.rint((x * scale[..., None] + 1.0) * 0.5 * STEPS), 0, 255)
    return np.concatenate([c, m[..., None]], axis=2).astype(np.uint8)


def decode_signed(encoded, value_range):
    """(h, w, 4) uint8 from encode_signed -> (h, w, 3) float64 values."""
    v = np.asarray(encoded, np.float64) / STEPS
    return (2.0 * v[..., :3] - 1.0) * v[..., 3:4] * value_range


def png(rgba, bottom_up=True):
    """An RGBA 8-bit PNG file's bytes for (h, w, 4) uint8 pixels; bottom_up: row 0 is the image's
    bottom (Blender's and the engine's order; a PNG stores the top row first). Each row is filtered
    with PNG's Up filter where that compresses better than none."""
    a = np.ascontiguousarray(rgba[::-1] if bottom_up else rgba, np.uint8)
    h, w = a.shape[:2]
    up = a.copy()
    up[1:] = a[1:] - a[:-1]                       # uint8 wraps: the Up filter's modulo 256

    def stream(rows, kind):
        return zlib.compress(np.concatenate([np.full((h, 1), kind, np.uint8), rows.reshape(h, w * 4)], axis=1)
                             .tobytes(), 9)
    data = min(stream(a, 0), stream(up, 2), key=len)

    def chunk(tag, body):
        return struct.pack(">I", len(body)) + tag + body + struct.pack(">I", zlib.crc32(tag + body) & 0xFFFFFFFF)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 6, 0, 0, 0))
            + chunk(b"IDAT", data) + chunk(b"IEND", b""))
