"""The glTF export's lightmap encoding (addon/photonlm_blender/gltf/rgbm.py, NumPy only): RGBM in an
8-bit PNG. Decoded values stay within the stated bound (m x range / 510 per channel; 1/255 of the
texel's largest channel above range / 255) over six decades of HDR values, and the PNG bytes decode
(zlib, PNG's None and Up filters) to the encoded pixels with the top row first."""
import importlib.util
import os
import struct
import zlib

import numpy as np

_PATH = os.path.join(os.path.dirname(__file__), "..", "..", "addon", "photonlm_blender", "gltf", "rgbm.py")
_spec = importlib.util.spec_from_file_location("rgbm", _PATH)
rgbm = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(rgbm)


def _hdr(h=64, w=48, seed=1):
    rng = np.random.default_rng(seed)
    return (10.0 ** rng.uniform(-4, 2, (h, w, 1)) * rng.uniform(0, 1, (h, w, 3))).astype(np.float32)


def test_decoded_within_the_stated_bound():
    rgb = _hdr()
    r = rgbm.lightmap_range(rgb)
    assert r == float(rgb.max())
    enc = rgbm.encode(rgb, r)
    dec = rgbm.decode(enc, r)
    err = np.abs(dec - rgb)
    assert np.all(err <= rgbm.error_bound(enc, r)[..., None] * (1 + 1e-9) + 1e-12)
    peak = rgb.max(axis=2)
    bright = peak >= r / 255.0
    assert bright.sum() > 100
    assert (err.max(axis=2)[bright] / peak[bright]).max() <= 1.0 / 255.0
    assert np.all(err[~bright] <= r / 130050.0 * (1 + 1e-9))
    assert enc[..., 3].max() == 255  # the brightest texel has m = 1


def test_black_negative_and_non_finite_texels_are_black():
    rgb = np.array([[[0, 0, 0], [-1, 2, 0], [np.nan, np.inf, 1]]], np.float32)
    enc = rgbm.encode(rgb, 2.0)
    assert enc[0, 0].tolist() == [0, 0, 0, 0]
    assert np.allclose(rgbm.decode(enc, 2.0)[0, 1], [0, 2, 0])
    assert np.allclose(rgbm.decode(enc, 2.0)[0, 2], [0, 0, 1], atol=2.0 / 510)
    assert rgbm.lightmap_range(np.zeros((2, 2, 3), np.float32)) == 1.0


def _read_png(data):
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, chunks = 8, {}
    while pos < len(data):
        n, tag = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        assert struct.unpack(">I", data[pos + 8 + n:pos + 12 + n])[0] == zlib.crc32(tag + body) & 0xFFFFFFFF
        chunks[tag] = chunks.get(tag, b"") + body
        pos += 12 + n
    w, h, depth, colour, _, _, _ = struct.unpack(">IIBBBBB", chunks[b"IHDR"])
    assert (depth, colour) == (8, 6)
    raw = np.frombuffer(zlib.decompress(chunks[b"IDAT"]), np.uint8).reshape(h, 1 + 4 * w)
    rows = raw[:, 1:].copy()
    for y in range(h):
        assert raw[y, 0] in (0, 2)
        if raw[y, 0] == 2 and y > 0:
            rows[y] = rows[y] + rows[y - 1]  # uint8 wraps
    return rows.reshape(h, w, 4)


def test_png_holds_the_pixels_top_row_first():
    rgb = _hdr(17, 23, seed=2)
    enc = rgbm.encode(rgb, rgbm.lightmap_range(rgb))
    assert np.array_equal(_read_png(rgbm.png(enc)), enc[::-1])
    assert np.array_equal(_read_png(rgbm.png(enc, bottom_up=False)), enc)
