"""BSP Lab demo: Build & Render through the add-on, headless.

    blender -b --factory-startup --python addon/tools/demo_headless.py -- --out out.png
    python addon/tools/demo_headless.py --out out.png        (with the `bpy` module)

Opens --blend FILE, or generates a default scene (meshes with a Subdivision
modifier, an instanced collection, a camera); registers the add-on from
addon/ (unless Blender already has it, e.g. as an installed extension); runs
`bpy.ops.bsplab.build_render()`; saves the "BSP Lab Preview" image block as a
PNG and prints the statistics shown in the panel.

The `bsplab` core must be importable: installed into Blender's Python, from
the extension's bundled wheels, or from the folders listed in
BSPLAB_PYTHONPATH (Blender's Python ignores PYTHONPATH).
"""

import argparse
import importlib.util
import math
import os
import pathlib
import sys

import bpy  # first: the bpy module makes bmesh importable
import bmesh  # noqa: E402

# The shipped add-on folder, beside this tool's folder.
ADDON_DIR = pathlib.Path(__file__).resolve().parents[2] / "addon"
ADDON_MODULE = "bsplab_addon"  # not "bsplab": that is the core's name


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    parser = argparse.ArgumentParser(prog="demo_headless.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("--blend", help="open this .blend instead of generating a scene")
    parser.add_argument("--out", default="bsplab_preview.png", help="PNG to write")
    parser.add_argument("--method", help="tree method (default: the add-on's)")
    parser.add_argument("--instances", choices=("two_level", "flatten"),
                        help="build instances in two levels or flattened (default: the "
                             "add-on's, two-level)")
    parser.add_argument("--mode", default="shaded", help="render mode")
    parser.add_argument("--preview", type=int, default=100,
                        help="preview size, %% of the scene's render resolution (default 100)")
    parser.add_argument("--resolution", default="640x360",
                        help="render resolution of the generated scene (WxH)")
    parser.add_argument("--compare-embree", action="store_true",
                        help="also trace with Embree and compare")
    return parser.parse_args(argv)


# -----------------------------------------------------------------------------
# The default scene


def mesh_object(scene, name, build, location=(0, 0, 0), collection=None):
    """An object whose mesh is made by build(bm), a bmesh.ops call."""
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    build(bm)
    bm.to_mesh(mesh)
    bm.free()
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    (collection or scene.collection).objects.link(obj)
    return obj


def generate_scene(resolution):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    width, height = (int(v) for v in resolution.lower().split("x"))
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100

    mesh_object(scene, "Ground", lambda bm: bmesh.ops.create_grid(
        bm, x_segments=1, y_segments=1, size=20.0))
    monkey = mesh_object(scene, "Suzanne", lambda bm: bmesh.ops.create_monkey(bm), (0, 0, 1.2))
    monkey.rotation_euler = (0, 0, math.radians(20))
    monkey.modifiers.new("Subdivision", 'SUBSURF').levels = 2
    cube = mesh_object(scene, "Cube", lambda bm: bmesh.ops.create_cube(bm, size=1.2), (2.6, 1.5, 0.6))
    cube.modifiers.new("Bevel", 'BEVEL').segments = 3

    # A small prop collection, kept out of the scene and shown three times
    # through collection-instance empties.
    props = bpy.data.collections.new("Props")
    mesh_object(scene, "Sphere", lambda bm: bmesh.ops.create_icosphere(
        bm, subdivisions=3, radius=0.5), (0, 0, 0.5), collection=props)
    mesh_object(scene, "Cone", lambda bm: bmesh.ops.create_cone(
        bm, cap_ends=True, segments=24, radius1=0.4, radius2=0.0, depth=1.0),
        (0.9, 0, 0.5), collection=props)
    for i, (x, y) in enumerate(((-3.5, 0.5), (-2.0, 3.0), (1.0, 4.0))):
        empty = bpy.data.objects.new("Props {}".format(i), None)
        empty.instance_type = 'COLLECTION'
        empty.instance_collection = props
        empty.location = (x, y, 0)
        scene.collection.objects.link(empty)

    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location = (6.5, -7.5, 4.5)
    scene.collection.objects.link(camera)
    import mathutils
    direction = mathutils.Vector((0, 0.8, 0.8)) - camera.location
    camera.rotation_euler = direction.to_track_quat('-Z', 'Y').to_euler()
    scene.camera = camera
    bpy.context.view_layer.update()
    return scene


# -----------------------------------------------------------------------------
# The add-on


def load_addon():
    """addon/ as a package (registering is up to the caller)."""
    if ADDON_MODULE in sys.modules:
        return sys.modules[ADDON_MODULE]
    spec = importlib.util.spec_from_file_location(
        ADDON_MODULE, ADDON_DIR / "__init__.py", submodule_search_locations=[str(ADDON_DIR)])
    module = importlib.util.module_from_spec(spec)
    sys.modules[ADDON_MODULE] = module
    spec.loader.exec_module(module)
    return module


def run(args):
    for entry in reversed(os.environ.get("BSPLAB_PYTHONPATH", "").split(os.pathsep)):
        if entry and entry not in sys.path:
            sys.path.insert(0, entry)

    if args.blend:
        bpy.ops.wm.open_mainfile(filepath=os.path.abspath(args.blend))
        scene = bpy.context.scene
    else:
        scene = generate_scene(args.resolution)

    addon = load_addon()
    if not hasattr(bpy.types.Scene, "bsplab"):
        addon.register()

    settings = scene.bsplab
    if args.method:
        settings.method = args.method
    if args.instances:
        settings.instances = args.instances
    settings.render_mode = args.mode
    settings.preview_percentage = args.preview
    settings.compare_with_embree = args.compare_embree

    print("BSP Lab demo: Blender {}, scene '{}', camera '{}'".format(
        bpy.app.version_string, scene.name, scene.camera.name if scene.camera else None))
    try:
        bpy.ops.bsplab.build_render()
    except RuntimeError as ex:  # the operator's error report
        print("BSP Lab demo failed: {}".format(str(ex).strip()), file=sys.stderr)
        return 1

    image = bpy.data.images[addon.jobs.preview.IMAGE_NAME]
    out = os.path.abspath(args.out)
    addon.jobs.preview.save_png(image, out)
    print(addon.build_render.statistics.table(settings.stats))
    print("Saved {} ({} x {})".format(out, image.size[0], image.size[1]))
    return 0


def main():
    code = run(parse_args())
    sys.stdout.flush()
    sys.stderr.flush()
    if not bpy.app.binary_path:
        # The bpy 4.2 module can crash in C++ static destructors at exit once
        # add-on classes were registered; the work is done, skip them.
        os._exit(code)
    sys.exit(code)


if __name__ == "__main__":
    main()
