"""Many bakes in one Blender, the way an artist works: bakes, cancels at random moments followed at
once by a new bake, undo after a bake, preview toggles, all in one process on a scene that uses
every kind of object the add-on exports.

Scene: a floor whose Principled material takes its Base Color from an Image Texture (an 8-bit
checker made in memory: the engine reads it from a temporary file), Suzanne with a Subdivision
Surface modifier (refined by the engine from its cage), a cube with a mesh Boolean (baked as its
mesh), a box minus a cylinder marked as primitives (an exact CSG solid), a smooth sphere lit
through an orientation lightmap, an L-system bush, a sun, a point light and a world colour.

Steps, drawn from a fixed seed until 110 bakes have finished:
- a bake (bpy.ops.photonlm.bake());
- a cancelled bake followed at once by a new one: the operator's worker path (BakeJob.run on a
  thread with a progress callback that answers the cancel flag, as the modal operator's Esc
  does; `blender -b` has no event loop for the modal operator itself), cancelled after a random
  number of progress calls or a random delay, concluded as the operator does (abort, or finish
  when the bake won the race), then bpy.ops.photonlm.bake();
- undo after a bake: two undo steps (a marker m, then m + 1), a bake that pushes its own step
  as from the UI (bpy.ops.photonlm.bake('EXEC_DEFAULT', True)), then Ctrl+Z twice
  (bpy.ops.ed.undo()), which must bring back marker m; background Blender has no undo stack
  until the first bpy.ops.ed.undo_push(), done once after the scene is built;
- a preview toggle (scene.photonlm.preview) followed by a bake.

Expected: Blender stays alive (a crash fails the test: Blender's crash handler is turned off so
that the signal reaches CTest at once; a hang fails it after 240 s); every bake
finishes with the floor, Suzanne, the Boolean cube, the CSG solid and the sphere baked, the CSG
solid traced exactly, the sphere's OL and the bush traced from its rules, and finite, non-negative
lightmaps; cancelled bakes leave the last finished bake's record untouched; at least 15 bakes are
really cancelled; undo restores the marker set before the bake; the floor stays textured. 15-20 s
on 2 idle cores (a minute when the machine is busy).
"""
import faulthandler
import math
import os
import random
import signal
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402

BAKES = int(os.environ.get("PHOTONLM_TEST_BAKES", 110))
WATCHDOG_SECONDS = 240
SEED = 20240
BAKED = ("floor", "suzanne", "bool_cube", "csg_box", "ball")


def checker_image(n=64, cells=4):
    img = bpy.data.images.new("stress_checker", n, n, alpha=True)  # byte, sRGB
    y, x = np.mgrid[0:n, 0:n]
    odd = ((x * cells // n + y * cells // n) % 2) == 1
    px = np.ones((n, n, 4), np.float32)
    px[odd, :3] = (0.9, 0.2, 0.1)
    img.pixels.foreach_set(px.ravel())
    return img


def add_mesh_object(op, name, material, **kwargs):
    op(**kwargs)
    obj = bpy.context.active_object
    obj.name = name
    if material is not None:
        obj.data.materials.append(material)
    return obj


def build():
    scenes.clear_scene()
    floor_mat = scenes.diffuse_material("floor_mat", (1.0, 1.0, 1.0), principled=True)
    nt = floor_mat.node_tree
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = checker_image()
    nt.links.new(tex.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    scenes.plane("floor", floor_mat, size=6.0, resolution=32)

    suzanne = add_mesh_object(bpy.ops.mesh.primitive_monkey_add, "suzanne",
                              scenes.diffuse_material("mat_suzanne", (0.7, 0.7, 0.7)), location=(0, 0, 1))
    sub = suzanne.modifiers.new("Subdivision", 'SUBSURF')
    sub.levels = sub.render_levels = 1
    suzanne.photonlm.resolution = 32

    # A mesh Boolean (operands not marked as primitives): baked as the evaluated mesh.
    cube = add_mesh_object(bpy.ops.mesh.primitive_cube_add, "bool_cube",
                           scenes.diffuse_material("mat_bool_cube", (0.6, 0.6, 0.6)), size=1.0, location=(2, 0, 0.5))
    cube.photonlm.resolution = 16
    cutter = add_mesh_object(bpy.ops.mesh.primitive_uv_sphere_add, "bool_cutter", None, radius=0.6,
                             location=(2.4, 0.4, 0.9))
    cutter.hide_render = True
    cutter.photonlm.enabled = False
    mod = cube.modifiers.new("bite", 'BOOLEAN')
    mod.operation = 'DIFFERENCE'
    mod.object = cutter

    # An exact CSG solid: a box minus a cylinder, both marked as primitives.
    box = add_mesh_object(bpy.ops.mesh.primitive_cube_add, "csg_box",
                          scenes.diffuse_material("mat_csg_box", (0.7, 0.7, 0.6)), size=0.8, location=(-2, 1.5, 0.4))
    box.photonlm.resolution = 16
    box.photonlm.primitive = 'BOX'
    hole = add_mesh_object(bpy.ops.mesh.primitive_cylinder_add, "csg_hole",
                           scenes.diffuse_material("mat_csg_hole", (0.7, 0.7, 0.6)), radius=0.2, depth=2.0,
                           location=(-2, 1.5, 0.4), rotation=(math.radians(90), 0, 0))
    hole.hide_render = True
    hole.photonlm.enabled = False
    hole.photonlm.primitive = 'CYLINDER'
    mod = box.modifiers.new("hole", 'BOOLEAN')
    mod.operation = 'DIFFERENCE'
    mod.object = hole

    # A smooth sphere lit through its orientation lightmap.
    ball = add_mesh_object(bpy.ops.mesh.primitive_uv_sphere_add, "ball",
                           scenes.diffuse_material("mat_ball", (0.5, 0.6, 0.7)), radius=0.5, segments=24,
                           ring_count=12, location=(-2, -1, 0.5))
    bpy.ops.object.shade_smooth()
    ball.photonlm.resolution = 16
    ball.photonlm.mode = 'ORIENTATION'

    # An L-system bush, traced from its rules (no lightmap of its own).
    bpy.context.scene.cursor.location = (1.5, -1.8, 0)
    assert bpy.ops.photonlm.add_lsystem(preset='BUSH') == {'FINISHED'}
    bush = bpy.context.active_object
    bush.name = "bush"
    bush.photonlm.lsystem.depth = 4
    assert bpy.ops.photonlm.update_lsystem() == {'FINISHED'}
    bush.data.materials.append(scenes.diffuse_material("mat_bush", (0.3, 0.5, 0.2)))

    scenes.add_light("sun", 'SUN', (0, 0, 10), rotation=(math.radians(35), 0, math.radians(20)), energy=3.0,
                     angle=0.05)
    scenes.add_light("lamp", 'POINT', (0.5, -0.5, 2.5), energy=200.0, shadow_soft_size=0.1)
    scenes.set_world_color((0.15, 0.2, 0.3))

    s = bpy.context.scene.photonlm
    s.output_dir = scenes.out_dir("bake_stress")
    s.photons = 30_000
    s.target_error = 0.0
    s.max_bounces = 4
    s.direct_samples = 2
    bpy.context.view_layer.update()


class Stress:
    def __init__(self, checks):
        self.checks = checks
        self.rng = random.Random(SEED)
        self.finished = 0
        self.cancelled = 0
        self.raced = 0  # cancel asked for, but the bake had already finished
        self.undos = 0
        self.toggles = 0
        self.bad = []   # first few problems, reported at the end
        self.seconds = []

    def problem(self, text):
        if len(self.bad) < 5:
            self.bad.append(text)

    def check_last(self, what):
        from photonlm_blender.writeback import record
        last = record.last()
        missing = [n for n in BAKED if n not in last.get("objects", {})]
        if missing:
            self.problem("%s: objects without a lightmap: %s" % (what, missing))
        for name, info in last.get("objects", {}).items():
            rgb = info.get("rgb")
            if rgb is not None and not (np.all(np.isfinite(rgb)) and rgb.min() >= 0.0):
                self.problem("%s: lightmap of %s not finite or negative" % (what, name))
        if "csg_box" not in last.get("csg_objects", []):
            self.problem("%s: csg_box not traced as a CSG solid" % what)
        if "ball" not in last.get("ols", {}):
            self.problem("%s: the ball has no orientation lightmap" % what)
        if "bush" not in last.get("lsystems", []):
            self.problem("%s: the bush was not traced from its rules" % what)

    def bake(self, what, undo=False):
        s = bpy.context.scene.photonlm
        s.seed = self.rng.randrange(1 << 20)
        t0 = time.perf_counter()
        # undo=True: the operator pushes its undo step, as when run from the UI.
        res = bpy.ops.photonlm.bake('EXEC_DEFAULT', True) if undo else bpy.ops.photonlm.bake()
        self.seconds.append(time.perf_counter() - t0)
        if res != {'FINISHED'}:
            self.problem("%s: bake returned %s" % (what, res))
            return
        self.finished += 1
        self.check_last(what)

    def cancel_then_bake(self):
        """The modal operator's worker path, cancelled at a random moment, then a bake at once."""
        from photonlm_blender.bake import job as bake
        from photonlm_blender.writeback import record
        before = record.last()
        ctx = bpy.context
        job = bake.BakeJob(ctx)
        cancel = threading.Event()
        calls = [0]
        after_calls = self.rng.randrange(0, 8) if self.rng.random() < 0.5 else None

        def progress(fraction, stage):  # PHOTONLM_OT_bake._progress: store, never touch bpy
            calls[0] += 1
            if after_calls is not None and calls[0] > after_calls:
                cancel.set()
            return not cancel.is_set()

        worker = threading.Thread(target=job.run, args=(progress,), name="photonlm-bake", daemon=True)
        worker.start()
        if after_calls is None:
            time.sleep(self.rng.uniform(0.0, 0.05))
            cancel.set()  # what Esc does
        worker.join()
        if job.error:
            self.problem("cancelled bake failed: %s" % job.error)
            job.abort(ctx)
        elif job.cancelled:
            job.abort(ctx)
            self.cancelled += 1
            now = record.last()
            if now.get("objects") is not before.get("objects") or now.get("stats") != before.get("stats"):
                self.problem("a cancelled bake changed the last bake's record")
        else:
            job.finish(ctx)
            self.raced += 1
        self.bake("bake right after a cancel")

    def undo_after_bake(self):
        """Two undo steps, a bake that pushes its own (as from the UI), then Ctrl+Z twice."""
        scene = bpy.context.scene
        marker = self.rng.randrange(1 << 20)
        scene["stress_marker"] = marker
        bpy.ops.ed.undo_push(message="marker")
        scene["stress_marker"] = marker + 1
        bpy.ops.ed.undo_push(message="marker + 1")
        self.bake("bake before undo", undo=True)
        for _ in range(2):
            if bpy.ops.ed.undo() != {'FINISHED'}:
                self.problem("undo did not run")
        self.undos += 1
        now = bpy.context.scene.get("stress_marker")
        if now != marker:
            self.problem("undo twice after a bake: marker %s, expected %s" % (now, marker))

    def toggle_preview(self):
        s = bpy.context.scene.photonlm
        s.preview = not s.preview
        self.toggles += 1
        self.bake("bake after a preview toggle")

    def run(self):
        t0 = time.perf_counter()
        steps = [(0.35, self.bake), (0.35, self.cancel_then_bake), (0.15, self.undo_after_bake),
                 (0.15, self.toggle_preview)]
        step = 0
        while self.finished < BAKES:
            x, acc = self.rng.random(), 0.0
            for weight, fn in steps:
                acc += weight
                if x < acc:
                    break
            if fn == self.bake:
                fn("bake")
            else:
                fn()
            step += 1
            if step % 10 == 0:
                print("step %d: %d bakes finished, %d cancelled, %d undos, %d preview toggles (%.1f s)"
                      % (step, self.finished, self.cancelled, self.undos, self.toggles, time.perf_counter() - t0),
                      flush=True)
        total = time.perf_counter() - t0
        c = self.checks
        c.check(self.finished >= BAKES, "%d bakes finished in one Blender (%.1f s, median bake %.2f s)"
                % (self.finished, total, float(np.median(self.seconds))))
        c.check(not self.bad, "every bake complete: CSG solid, OL, L-system, finite lightmaps (%s)" % self.bad)
        c.check(self.cancelled >= 15, "%d bakes cancelled at random moments and followed at once by a new bake "
                "(%d more finished before the cancel)" % (self.cancelled, self.raced))
        c.check(self.undos >= 5, "%d undos after a bake brought back the state before it" % self.undos)
        c.check(self.toggles >= 5, "%d preview toggles, each followed by a bake" % self.toggles)


def floor_textured(checks, when):
    from photonlm_blender.export import materials
    info = materials.read_material(bpy.data.materials["floor_mat"])
    checks.check(info.albedo_texture is not None, "%s: the floor's Base Color goes to the engine as an image "
                 "texture" % when)


def fail_fast():
    """A crash kills Blender at once (its crash handler allocates, and on a corrupted heap it can
    hang), and a hang ends the test after WATCHDOG_SECONDS with the Python stacks printed."""
    for sig in (signal.SIGSEGV, signal.SIGBUS, signal.SIGFPE, signal.SIGILL, signal.SIGABRT):
        signal.signal(sig, signal.SIG_DFL)
    faulthandler.dump_traceback_later(WATCHDOG_SECONDS, exit=True)


def main():
    fail_fast()
    checks = scenes.Checks("bake_stress")
    scenes.setup_paths()
    build()
    # Background Blender starts without an undo stack: the first push creates it.
    bpy.ops.ed.undo_push(message="scene built")
    floor_textured(checks, "before the bakes")
    Stress(checks).run()
    floor_textured(checks, "after the bakes and undos")
    dupes = [im.name for im in bpy.data.images if ".0" in im.name]
    checks.check(not dupes, "no duplicate images (%s)" % dupes)
    faulthandler.cancel_dump_traceback_later()
    checks.finish()


main()
