#!/usr/bin/env python3
"""The web viewer beside Blender: a scene baked with the add-on in Blender 5.2, exported to .glb,
rendered in EEVEE with the lightmap preview (Standard view transform) and shown by the web viewer
(web/dist) in headless Chromium from the same camera; the two side by side, and the numbers of
docs/gltf.md (the difference on the lit pixels, the export's time and sizes, the page's time to
its first frame over a few loads).

    (cd web && npm ci && npm run build)
    /usr/bin/python3 docs/make_web_screenshots.py [artist|room|cornell|bricks] [OUT_DIR]

writes blender.png, browser.png, side_by_side.png, difference.png and numbers.json into OUT_DIR
(default /tmp/web_shots/<scene>), and with PHOTONLM_DOC_SAVE=1 copies side_by_side.png to
docs/images/web_vs_blender.png. The scene is the artist's room (default), the sunlit room of the
light groups test without its groups, the Cornell box or the directional brick wall
(blend_tests/web_viewer_scene.py; docs/images/web_vs_blender_directional.png is its side_by_side.png),
640 x 480.
"""
import json
import os
import shutil
import statistics
import sys

SRC = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(SRC, "web", "test"))
import test_web_viewer as wv  # noqa: E402

LOADS = 5  # page loads timed


def main():
    scene = sys.argv[1] if len(sys.argv) > 1 else "artist"
    out = os.path.abspath(sys.argv[2]) if len(sys.argv) > 2 else os.path.join("/tmp/web_shots", scene)
    os.makedirs(out, exist_ok=True)
    view = wv.bake_and_render(out, scene, 640, 480, blender="5.2")
    blender_png, browser_png = os.path.join(out, "blender.png"), os.path.join(out, "browser.png")
    times = [wv.screenshot(out, view, browser_png)[0] for _ in range(LOADS)]
    result = wv.compare(browser_png, blender_png)
    wv.side_by_side(blender_png, browser_png, os.path.join(out, "side_by_side.png"))
    texels = sum(v["texels"] for v in view["lightmaps"].values())
    png_bytes = sum(v["png_bytes"] for v in view["lightmaps"].values())
    numbers = dict(scene=scene, blender=view["blender"], lit_pixels=result["pixels"],
                   mean_difference=result["mean_difference"], bias=result["bias"],
                   export_seconds=view["export_seconds"], glb_bytes=view["glb_bytes"], lightmaps=len(view["lightmaps"]),
                   texels=texels, png_bytes=png_bytes, png_mb_per_million_texels=png_bytes / texels,
                   first_frame_ms=times, first_frame_ms_median=statistics.median(times))
    with open(os.path.join(out, "numbers.json"), "w") as f:
        json.dump(numbers, f, indent=1)
    print(json.dumps(numbers, indent=1))
    if os.environ.get("PHOTONLM_DOC_SAVE") == "1":
        shutil.copy(os.path.join(out, "side_by_side.png"), os.path.join(SRC, "docs", "images", "web_vs_blender.png"))
        print("make_web_screenshots: wrote docs/images/web_vs_blender.png")


main()
