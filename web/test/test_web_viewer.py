#!/usr/bin/env python3
"""The web viewer (web/) shows a baked scene as Blender's lightmap preview does.

A Cornell box is baked with the add-on in Blender, exported with File > Export > glTF with PhotonLM
lightmaps and rendered in EEVEE with the lightmap preview under the Standard view transform
(blend_tests/web_viewer_scene.py); the page (web/dist, built by `npm ci && npm run build` in web/)
opens the .glb in headless Chromium from the same camera at the same size (320 x 240), served from
127.0.0.1, and its screenshot is compared with the render, both read back to linear values:

- on the lit pixels (both above 2 % grey, and 2 pixels away from the background, where the two
  renderers' anti-aliasing differs), the mean of |browser - Blender| / Blender per pixel (channels
  summed) is at most MAX_MEAN_DIFFERENCE (measured: 0.55 %; what is left is the edges of faces, where
  the two renderers' anti-aliasing and texel look-ups differ);
- the lit pixels' mean brightness agrees within MAX_BIAS (measured: 0.1 %): lightMapIntensity =
  pi x range is the right scale;
- the page is ready (window.__photonlmReady) within a minute, with nothing in its console's
  warnings and errors; its time to the first frame is printed.

    /usr/bin/python3 web/test/test_web_viewer.py    (PHOTONLM_WEB_BLENDER=5.2|4.3|3.4, default 5.2)

(Measured with the scene made in 4.3: 0.55 % and -0.12 %; in 3.4: 0.66 % and -0.07 %.)

Writes blender.png, browser.png, side_by_side.png and difference.png into
$PHOTONLM_TEST_OUT/web_viewer (default build/blend_test_out/5.2/web_viewer).
"""
import json
import os
import shutil
import subprocess
import sys
import time

import numpy as np
from PIL import Image, ImageDraw

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from chromium import Chromium, serve  # noqa: E402

SRC = os.environ.get("PHOTONLM_SOURCE_DIR") or os.path.dirname(os.path.dirname(HERE))
MAX_MEAN_DIFFERENCE = 0.02
MAX_MEAN_DIFFERENCE_BRICKS = 0.04  # measured 2.2 %: the bricks' sharp edges, a pixel off between renderers
MAX_BIAS = 0.01
LIT = 0.02        # linear grey a pixel must exceed in both images to count as lit
MARGIN = 2        # pixels kept away from the background


def linear(path):
    """An 8-bit sRGB PNG as linear RGB floats (h, w, 3)."""
    x = np.asarray(Image.open(path).convert("RGB"), np.float64) / 255.0
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def lit_mask(a, b, lit=LIT, margin=MARGIN):
    """Pixels lit in both images, `margin` pixels away from any unlit one."""
    mask = (a.mean(axis=2) > lit) & (b.mean(axis=2) > lit)
    padded = np.pad(mask, margin, constant_values=False)
    h, w = mask.shape
    out = mask.copy()
    for dy in range(2 * margin + 1):
        for dx in range(2 * margin + 1):
            out &= padded[dy:dy + h, dx:dx + w]
    return out


def compare(browser_png, blender_png):
    """{mean_difference, bias, pixels, per_pixel}: the mean relative difference of the lit pixels,
    the ratio of their mean brightness minus 1, their count, and the per-pixel relative difference."""
    a, b = linear(browser_png), linear(blender_png)
    if a.shape != b.shape:
        raise AssertionError("the screenshot is %s, the render %s" % (a.shape, b.shape))
    mask = lit_mask(a, b)
    per_pixel = np.abs(a - b).sum(axis=2) / np.maximum(b.sum(axis=2), 1e-6)
    # The spread of the lit pixels' brightness, relative to their mean (a normal map's relief).
    spread = [float(x.mean(axis=2)[mask].std() / x.mean(axis=2)[mask].mean()) for x in (a, b)]
    return dict(mean_difference=float(per_pixel[mask].mean()), bias=float(a[mask].mean() / b[mask].mean() - 1.0),
                pixels=int(mask.sum()), per_pixel=np.where(mask, per_pixel, 0.0), spread=spread)


def side_by_side(left_png, right_png, path, labels=("Blender: EEVEE, lightmap preview", "Chromium: web viewer")):
    """The two images next to each other, each labelled, with a gap."""
    left, right = Image.open(left_png).convert("RGB"), Image.open(right_png).convert("RGB")
    w, h = left.size
    gap = max(4, w // 80)
    out = Image.new("RGB", (2 * w + gap, h), (255, 255, 255))
    out.paste(left, (0, 0))
    out.paste(right, (w + gap, 0))
    draw = ImageDraw.Draw(out)
    for x, text in ((0, labels[0]), (w + gap, labels[1])):
        box = draw.textbbox((x + 6, 6), text)
        draw.rectangle((box[0] - 3, box[1] - 3, box[2] + 3, box[3] + 3), fill=(0, 0, 0))
        draw.text((x + 6, 6), text, fill=(255, 255, 255))
    out.save(path)


def page_url(base, view, glb="scene.glb", ui=False):
    def triple(v):
        return ",".join("%.6g" % c for c in v)
    return "%sindex.html?file=%s&cam=%s&target=%s&fov=%.6g%s" % (
        base, glb, triple(view["cam"]), triple(view["target"]), view["fov"], "" if ui else "&ui=0")


def bake_and_render(out, scene="cornell", width=320, height=240, photons=None, blender=None):
    """Runs blend_tests/web_viewer_scene.py in a Blender (scripts/blender.sh); returns view.json's dict."""
    blender = blender or os.environ.get("PHOTONLM_WEB_BLENDER", "5.2")
    args = [os.path.join(SRC, "scripts", "blender.sh"), blender, "-b", "--factory-startup", "--python-exit-code", "1",
            "--python", os.path.join(SRC, "blend_tests", "web_viewer_scene.py"), "--",
            out, scene, str(width), str(height)]
    if photons:
        args.append(str(photons))
    env = dict(os.environ, PHOTONLM_SOURCE_DIR=SRC)
    env.setdefault("PHOTONLM_TEST_OUT", os.path.dirname(out))  # a Blender in a Debian root sees it
    t0 = time.perf_counter()
    proc = subprocess.run(args, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = [line for line in proc.stdout.splitlines() if "web_viewer_scene" in line or "Error" in line]
    print("\n".join(lines), flush=True)
    if proc.returncode != 0:
        print(proc.stdout[-6000:])
        raise SystemExit("web viewer: Blender failed (exit %d)" % proc.returncode)
    print("web viewer: Blender %s baked, exported and rendered in %.1f s" % (blender, time.perf_counter() - t0))
    with open(os.path.join(out, "view.json")) as f:
        return json.load(f)


def site(out, dist=None):
    """out/site: the built page and scene.glb, to be served."""
    dist = dist or os.path.join(SRC, "web", "dist")
    if not os.path.isfile(os.path.join(dist, "index.html")):
        raise SystemExit("web viewer: %s/index.html is missing: build the page first "
                         "(cd web && npm ci && npm run build)" % dist)
    root = os.path.join(out, "site")
    shutil.rmtree(root, ignore_errors=True)
    shutil.copytree(dist, root)
    shutil.copy(os.path.join(out, "scene.glb"), root)
    return root


def screenshot(out, view, path):
    """The page's screenshot of scene.glb from the view; returns its time to the first frame (ms)
    and the page's console warnings and errors."""
    with serve(site(out)) as base, Chromium(view["width"], view["height"]) as browser:
        browser.open(page_url(base, view))
        browser.wait_for("window.__photonlmReady === true", error="window.__photonlmError")
        first_frame = browser.evaluate("window.__photonlmFirstFrameMs")
        with open(path, "wb") as f:
            f.write(browser.screenshot())
        return first_frame, list(browser.console)


def main():
    build = os.environ.get("PHOTONLM_BUILD_DIR") or os.path.join(SRC, "build")
    base = os.environ.get("PHOTONLM_TEST_OUT") or os.path.join(build, "blend_test_out", "5.2")
    out = os.path.join(base, "web_viewer")
    os.makedirs(out, exist_ok=True)
    failed, checks = [], [0]

    def check(ok, text):
        checks[0] += 1
        print("[%s] web_viewer: %s" % ("PASS" if ok else "FAIL", text), flush=True)
        if not ok:
            failed.append(text)

    compare_scene(out, bake_and_render(out), check)
    # The room with light groups, mixed before the export: the page mixes the layers as the preview does.
    groups_out = os.path.join(base, "web_viewer_groups")
    os.makedirs(groups_out, exist_ok=True)
    compare_scene(groups_out, bake_and_render(groups_out, scene="groups"), check, "light groups mixed: ")
    # A brick wall's normal map under directional lightmaps: the page evaluates the SH bands at the
    # normal map's normals as the preview does (the bricks' edges, sampled nearest, differ by a pixel).
    bricks_out = os.path.join(base, "web_viewer_bricks")
    os.makedirs(bricks_out, exist_ok=True)
    result = compare_scene(bricks_out, bake_and_render(bricks_out, "bricks", 640, 480), check, "directional: ",
                           max_mean=MAX_MEAN_DIFFERENCE_BRICKS, min_lit=0.2)
    browser_spread, blender_spread = result["spread"]
    check(blender_spread > 0.05 and 0.8 <= browser_spread / blender_spread <= 1.25,
          "directional: the bricks' relief, the lit pixels' spread, browser %.3f against Blender %.3f"
          % (browser_spread, blender_spread))
    print("web_viewer: %d checks, %d failed (images in %s)" % (checks[0], len(failed), out))
    if failed:
        raise SystemExit("web_viewer FAILED: " + "; ".join(failed))


def compare_scene(out, view, check, what="", max_mean=MAX_MEAN_DIFFERENCE, min_lit=0.5):
    """The page's screenshot of out/scene.glb against Blender's render out/blender.png; returns the
    comparison (compare)."""
    texels = sum(v["texels"] for v in view["lightmaps"].values())
    png_bytes = sum(v["png_bytes"] for v in view["lightmaps"].values())
    print("web viewer: export %.2f s, %d bytes; lightmap PNGs %d bytes for %d texels (%.0f bytes per texel)"
          % (view["export_seconds"], view["glb_bytes"], png_bytes, texels, png_bytes / texels))
    blender_png, browser_png = os.path.join(out, "blender.png"), os.path.join(out, "browser.png")
    t0 = time.perf_counter()
    first_frame, console = screenshot(out, view, browser_png)
    check(first_frame is not None, what + "the page drew scene.glb in Chromium: first frame %.0f ms after navigation "
          "(%.1f s with Chromium's start)" % (first_frame or -1, time.perf_counter() - t0))
    check(not console, what + "the page's console has no warnings or errors (%s)" % ("; ".join(console) or "none"))
    result = compare(browser_png, blender_png)
    check(result["pixels"] > min_lit * view["width"] * view["height"],
          what + "%d lit pixels compared (of %d)" % (result["pixels"], view["width"] * view["height"]))
    check(result["mean_difference"] <= max_mean,
          what + "mean relative difference browser vs Blender on the lit pixels: %.2f %% (bound %.0f %%)"
          % (100 * result["mean_difference"], 100 * max_mean))
    check(abs(result["bias"]) <= MAX_BIAS, what + "mean brightness browser / Blender - 1: %+.2f %% (bound %.0f %%)"
          % (100 * result["bias"], 100 * MAX_BIAS))
    side_by_side(blender_png, browser_png, os.path.join(out, "side_by_side.png"))
    Image.fromarray((np.clip(result["per_pixel"] * 10.0, 0, 1) * 255).astype(np.uint8)).save(
        os.path.join(out, "difference.png"))
    return result


if __name__ == "__main__":
    main()
