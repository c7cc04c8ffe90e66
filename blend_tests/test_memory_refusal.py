"""A bake that cannot fit in memory is refused with the engine's message, and nothing changes.

After a small lit bake, quads at the largest Resolution the add-on allows (8192 x 8192, each
estimated at about 27 GB) are added, as many as it takes for the estimate to pass 1.5 x this
machine's free memory. The engine refuses before it allocates: bpy.ops.photonlm.bake() raises
'bake refused: the bake would need about ... of memory (mesh '<object>', 8192 x 8192 texels ...)';
images, materials, UV maps, files and the statistics are as they were, and the refusal takes
seconds and little memory. The Resolution field stops at 8192. The engine's warning that a bake
comes close to the memory free (past 60 % of it: not provoked here, on a machine others share)
is reported after the bake's summary and not among the other engine warnings: checked with a
warning of the engine's wording added to a real result.
"""
import math
import os
import resource
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402
import unchanged  # noqa: E402

import bpy  # noqa: E402

TEXEL_BYTES = 240 + 160  # the engine's estimate per covered texel
SIDE = 8192


def free_memory():
    """Bytes this process may still allocate, as the engine reads it: MemAvailable, or the cgroup's
    limit less its use where that is lower."""
    free = 0
    with open("/proc/meminfo") as f:
        for line in f:
            if line.startswith("MemAvailable:"):
                free = int(line.split()[1]) * 1024
    for limit_path, use_path in (("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
                                 ("/sys/fs/cgroup/memory/memory.limit_in_bytes",
                                  "/sys/fs/cgroup/memory/memory.usage_in_bytes")):
        try:
            limit = open(limit_path).read().strip()
            use = int(open(use_path).read().strip())
        except (OSError, ValueError):
            continue
        if limit.isdigit() and int(limit) - use < free:
            free = max(int(limit) - use, 0)
    return free


def main():
    scenes.setup_paths()
    from photonlm_blender.writeback import images
    import photonlm
    checks = scenes.Checks("memory_refusal")
    scene = scenes.clear_scene()
    scene.photonlm.output_dir = scenes.out_dir("memory") + "/"
    scenes.plane("floor", scenes.diffuse_material("floor_mat", (0.7, 0.7, 0.7)), size=4.0, resolution=32)
    scenes.add_light("sun", 'SUN', (0, 0, 5), rotation=(0.4, 0.2, 0), energy=3.0)

    # -- the engine's near-the-limit warning is reported last ------------------------------------------------------
    real = photonlm.Result.warnings
    memory_warning = ("the bake may need about 9.1 GB of memory (mesh 'floor', 32 x 32 texels: about 400 KB), "
                      "close to the 12.0 GB free")
    photonlm.Result.warnings = property(lambda self: real.fget(self) + [memory_warning])
    try:
        last = scenes.photonlm_bake(300_000, 8, seed=1, target_error=0.05)
    finally:
        photonlm.Result.warnings = real
    texts = [t for _, t in last["reports"]]
    checks.check(texts and texts[-1] == "engine: " + memory_warning,
                 "the memory warning is the last report, after the summary (%s)" % (texts[-1:],))
    checks.check(texts.count("engine: " + memory_warning) == 1, "and it is reported once")

    # -- the Resolution field --------------------------------------------------------------------------------------
    prop = bpy.data.objects["floor"].photonlm.bl_rna.properties["resolution"]
    checks.check(prop.hard_max == 8192 and prop.soft_max == 4096 and "bytes per texel" in prop.description,
                 "Resolution: hard max %d, soft max %d, the description names the memory" % (prop.hard_max, prop.soft_max))
    floor = bpy.data.objects["floor"]
    floor.photonlm.resolution = 16384
    checks.check(floor.photonlm.resolution == 8192, "16384 is clamped to 8192")
    floor.photonlm.resolution = 32

    # -- the refusal ------------------------------------------------------------------------------------------------------
    free = free_memory()
    per_object = SIDE * SIDE * TEXEL_BYTES
    count = max(1, math.ceil(1.5 * free / per_object))
    names = []
    for i in range(count):
        obj = scenes.plane("Huge Wall %d" % (i + 1), scenes.diffuse_material("wall_mat_%d" % i, (0.6,) * 3),
                           size=2.0, z=1.0 + 0.1 * i, resolution=SIDE)
        names.append(obj.name)
    folder = images.output_directory(scene)
    before = unchanged.snapshot(folder)
    rss_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    t0 = time.perf_counter()
    try:
        bpy.ops.photonlm.bake()
        error = None
    except RuntimeError as e:
        error = str(e)
    seconds = time.perf_counter() - t0
    rss_after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    print("memory_refusal: %d objects of %d x %d (%.1f GB estimated each), %.1f GB free; refused in %.2f s"
          % (count, SIDE, SIDE, per_object / 1e9, free / 1e9, seconds))
    checks.check(error is not None and "bake refused: the bake would need about" in error and "memory" in error,
                 "the bake is refused with the engine's message: %s" % error)
    named = [n for n in names if error is not None and "'%s'" % n in error]
    checks.check(bool(named) and "8192 x 8192 texels" in error, "the message names the object and its texels %s"
                 % named)
    checks.check(error is not None and "lower the lightmap resolution" in error, "and says what to do")
    checks.check(seconds < 20.0, "refused before baking (%.2f s)" % seconds)
    checks.check(rss_after - rss_before < 2e9, "refused before allocating (peak memory grew by %.0f MB)"
                 % ((rss_after - rss_before) / 1e6))
    diff = unchanged.differences(before, unchanged.snapshot(folder))
    checks.check(not diff, "nothing changed: images, materials, UV maps, files, statistics %s" % diff)
    checks.check(not any(bpy.data.images.get(n + "_lightmap") for n in names), "no lightmap images for the walls")
    checks.finish()


try:
    main()
except Exception:
    import traceback
    traceback.print_exc()
    sys.exit(1)
