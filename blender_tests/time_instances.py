"""The instanced-scene button times of issue 24: Suzanne at Subdivision
level 3 (61,952 triangles) in a grid of collection instances, camera above,
Build & Render at 50 % of 1920 x 1080, Instances: Two-level (or Flatten).

    blender_tests/time_instances.sh [-- --side 10 --instances two_level]

Prints the first press (every tree built), a press after moving one
instance (the top level rebuilt), a press after only the shading changed
(nothing rebuilt), each with the panel's build and render times, and the
process's peak resident memory (ru_maxrss, the whole Blender process).
"""

import argparse
import pathlib
import resource
import sys
import time

import bpy

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import time_button  # noqa: E402  (the timing scripts' shared set-up)


def make_grid(side, level):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 1920, 1080
    mesh_coll = bpy.data.collections.new("Suzanne")  # not linked: seen only through instances
    bpy.ops.mesh.primitive_monkey_add()
    suzanne = bpy.context.active_object
    for c in list(suzanne.users_collection):
        c.objects.unlink(suzanne)
    mesh_coll.objects.link(suzanne)
    mod = suzanne.modifiers.new("Subdivision", "SUBSURF")
    mod.levels = mod.render_levels = level
    step = 3.0
    grid = []
    for i in range(side):
        for j in range(side):
            inst = bpy.data.objects.new(f"Grid {i} {j}", None)
            inst.instance_type = "COLLECTION"
            inst.instance_collection = mesh_coll
            inst.location = (step * i, step * j, 0.0)
            scene.collection.objects.link(inst)
            grid.append(inst)
    cam_data = bpy.data.cameras.new("Camera")
    cam = bpy.data.objects.new("Camera", cam_data)
    scene.collection.objects.link(cam)
    centre = step * (side - 1) / 2
    cam.location = (centre, centre - 0.6 * step * side, 1.1 * step * side)
    cam.rotation_euler = (0.5, 0.0, 0.0)
    scene.camera = cam
    bpy.context.view_layer.update()
    return scene, grid


def press(addon, settings, label):
    start = time.perf_counter()
    bpy.ops.bsplab.build_render()
    wall = time.perf_counter() - start
    stats = settings.stats
    build = stats["build"]
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20  # KiB -> GiB
    print(f"  {label}: {wall:.3f} s (panel: build {build['build_seconds']:.3f} s, render "
          f"{stats['render']['seconds']:.3f} s); peak RSS so far {rss:.2f} GiB", flush=True)
    return wall


def main():
    p = argparse.ArgumentParser(prog="time_instances.py")
    p.add_argument("--side", type=int, default=10)
    p.add_argument("--level", type=int, default=3)
    p.add_argument("--method", default="kd")
    p.add_argument("--instances", default="two_level", help="the panel's Instances choice")
    args = p.parse_args(time_button.script_argv())
    time_button.add_core_paths()
    scene, grid = make_grid(args.side, args.level)
    addon, settings = time_button.ready_addon(scene, args.method, 50)
    settings.instances = args.instances
    if hasattr(settings, "count_steps"):
        settings.count_steps = False
    print(f"time_instances: Blender {bpy.app.version_string}, {args.side}x{args.side} Suzanne "
          f"(level {args.level}), {args.method}, Instances {args.instances}")
    addon.state.STATE.forget_trees()
    press(addon, settings, "first press")
    grid[len(grid) // 2].location.x += 0.7
    bpy.context.view_layer.update()
    press(addon, settings, "one instance moved")
    settings.render_mode = "normal"
    press(addon, settings, "shading changed")
    s = settings.stats["build"]
    print("time_instances: build stats " + ", ".join(
        f"{k} {s[k]}" for k in sorted(s) if isinstance(s[k], (int, float, str)))[:900])
    return 0


if __name__ == "__main__":
    time_button.run(main)
