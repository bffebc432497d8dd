"""Shared helpers of the Blender tests: loading the add-on, building scenes.

Imported both by pytest (in-process `bpy`, or inside a Blender binary) and by
the subprocess scripts of the tests, so it depends on nothing but bpy/numpy.
"""

import importlib
import os
import pathlib
import sys
import tempfile

import bpy
import numpy as np
from mathutils import Vector

REPO = pathlib.Path(__file__).resolve().parents[1]
ADDON_DIR = REPO / "addon"
# addon/'s folders that stay out of the zips (addon/tools/build_extension.py's NOT_SHIPPED).
NOT_SHIPPED = ("tests", "tools")
# Not "bsplab": that is the core's module name.
ADDON_MODULE = "bsplab_addon"


def shipped_modules():
    """The add-on's .py files that the zips carry, relative to addon/ ("state.py")."""
    return {path.relative_to(ADDON_DIR).as_posix() for path in ADDON_DIR.rglob("*.py")
            if path.relative_to(ADDON_DIR).parts[0] not in NOT_SHIPPED}


# What build_test_scene() puts in view, in triangles.
SUBDIV_CUBE_TRIANGLES = 6 * 4 ** 2 * 2  # 6 quads, Subdivision level 2, 2 tris per quad
PROP_TRIANGLES = 4 + 2  # tetrahedron + quad in the instanced collection
PROP_INSTANCES = 2
GROUND_TRIANGLES = 2
EXPECTED_TRIANGLES = SUBDIV_CUBE_TRIANGLES + PROP_INSTANCES * PROP_TRIANGLES + GROUND_TRIANGLES


def blender_version():
    return tuple(bpy.app.version)


def add_core_paths():
    """Make `bsplab` importable from BSPLAB_PYTHONPATH (used inside Blender,
    whose Python ignores PYTHONPATH)."""
    for entry in reversed(os.environ.get("BSPLAB_PYTHONPATH", "").split(os.pathsep)):
        if entry and entry not in sys.path:
            sys.path.insert(0, entry)


def load_addon():
    """Import `addon/` as the package `bsplab_addon` (not registered yet).

    Through a symlink on sys.path, like an installed add-on, so that
    importlib.reload (Blender's Reload Scripts) can find it again.
    """
    if ADDON_MODULE in sys.modules:
        return sys.modules[ADDON_MODULE]
    folder = pathlib.Path(tempfile.mkdtemp(prefix="bsplab-addon-"))
    (folder / ADDON_MODULE).symlink_to(ADDON_DIR, target_is_directory=True)
    sys.path.insert(0, str(folder))
    return importlib.import_module(ADDON_MODULE)


def reset_file(instances="flatten"):
    """An empty file with factory settings; returns its scene.

    Its Build & Render builds `instances` ("flatten", or "two_level", the
    add-on's default): the suite written before two-level builds checks a
    flat tree's numbers and pixels (nodes, leaves, the inspector and the
    overlay, which draw flat trees only), so it pins Flatten; the two-level
    tests (test_instances.py) ask for "two_level"."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    if hasattr(scene, "bsplab"):
        scene.bsplab.instances = instances
    return scene


def make_mesh(name, verts, faces):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(v) for v in verts], [], [tuple(f) for f in faces])
    mesh.update()
    return mesh


def cube_mesh(name, size=1.0):
    h = size / 2.0
    verts = [(x, y, z) for x in (-h, h) for y in (-h, h) for z in (-h, h)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return make_mesh(name, verts, faces)


def quad_mesh(name, size=1.0):
    h = size / 2.0
    return make_mesh(name, [(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)], [(0, 1, 2, 3)])


def tetra_mesh(name, size=1.0):
    verts = np.array([(1, 1, 1), (1, -1, -1), (-1, 1, -1), (-1, -1, 1)], float) * size / 2
    return make_mesh(name, verts, [(0, 1, 2), (0, 3, 1), (0, 2, 3), (1, 3, 2)])


def link(scene, name, data, location=(0, 0, 0)):
    obj = bpy.data.objects.new(name, data)
    obj.location = location
    scene.collection.objects.link(obj)
    return obj


def look_at(obj, target):
    direction = Vector(target) - obj.location
    obj.rotation_euler = direction.to_track_quat('-Z', 'Y').to_euler()


def add_camera(scene, location=(0.0, -12.0, 3.0), target=(0.0, 0.0, 0.5), name="Camera"):
    cam = link(scene, name, bpy.data.cameras.new(name), location)
    look_at(cam, target)
    scene.camera = cam
    return cam


def build_test_scene(scene=None, camera=True):
    """The scene of the issue: a Subdivision modifier, an instanced collection,
    a hidden object, a non-mesh object and a camera.

    Returns a dict of the interesting objects.
    """
    scene = scene or bpy.context.scene
    scene.render.resolution_x = 160
    scene.render.resolution_y = 120
    scene.render.resolution_percentage = 100

    cube = link(scene, "Subdivided Cube", cube_mesh("Cube", 2.0), (0, 0, 1))
    subsurf = cube.modifiers.new("Subdivision", 'SUBSURF')
    subsurf.levels = 2
    subsurf.render_levels = 2

    ground = link(scene, "Ground", quad_mesh("Ground", 40.0), (0, 0, 0))

    # A collection that is not part of the scene, shown only through two
    # collection-instance empties: its objects count once per instance.
    props = bpy.data.collections.new("Props")
    tetra = bpy.data.objects.new("Tetra", tetra_mesh("Tetra", 1.0))
    tetra.location = (0, 0, 0.5)
    props.objects.link(tetra)
    props.objects.link(bpy.data.objects.new("Card", quad_mesh("Card", 1.0)))
    instancers = []
    for i, x in enumerate((-3.5, 3.5)):
        empty = link(scene, "Props Instance {}".format(i), None, (x, 0, 0.5))
        empty.instance_type = 'COLLECTION'
        empty.instance_collection = props
        instancers.append(empty)

    # Hidden in the viewport, right in front of the camera: if it leaked into
    # the extraction it would cover the whole preview.
    blocker = link(scene, "Hidden Blocker", quad_mesh("Blocker", 30.0), (0, -6, 2))
    blocker.rotation_euler = (np.pi / 2, 0, 0)
    blocker.hide_set(True)

    # A text object without characters: Blender renders nothing of it, and
    # the extraction (which reads text, curves, surfaces and metaballs as
    # the meshes they evaluate to) finds no faces in it. (A new text curve
    # says "Text"; test_instances.py reads one that does.)
    label = bpy.data.curves.new("Label", 'FONT')
    label.body = ""
    text = link(scene, "Label", label, (0, 2, 3))

    cam = add_camera(scene) if camera else None
    bpy.context.view_layer.update()
    return {"cube": cube, "ground": ground, "props": props, "instancers": instancers,
            "blocker": blocker, "text": text, "camera": cam}


def evaluated_triangle_count(depsgraph):
    """Triangles of the evaluated scene, counted the plain way: every drawn
    instance of an evaluated mesh (of a mesh object, or of a curve, text,
    surface or metaball, which Blender evaluates to meshes)."""
    total = 0
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type != 'MESH' or not inst.show_self:
            continue
        mesh = obj.to_mesh()
        mesh.calc_loop_triangles()
        total += len(mesh.loop_triangles)
        obj.to_mesh_clear()
    return total


def put_nan_vertex(mesh):
    """Make one coordinate of the mesh NaN (bad input for the core)."""
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    co[4] = np.nan
    mesh.vertices.foreach_set("co", co)
    mesh.update()


def image_pixels_top_down(image):
    """Pixels of an image block as (H, W, 4), row 0 at the top."""
    width, height = image.size
    flat = np.empty(width * height * 4, dtype=np.float32)
    image.pixels.foreach_get(flat)
    return flat.reshape(height, width, 4)[::-1]


def scene_snapshot(scene):
    """What an operator that failed must not have changed."""
    images = {}
    for image in bpy.data.images:
        pixels = np.empty(len(image.pixels), dtype=np.float32)
        image.pixels.foreach_get(pixels)
        images[image.name] = (tuple(image.size), image.source, pixels.tobytes())
    settings = scene.bsplab if hasattr(scene, "bsplab") else None
    return {
        "images": images,
        "stats": settings.stats_json if settings else None,
        "objects": sorted(o.name for o in bpy.data.objects),
        "meshes": sorted(m.name for m in bpy.data.meshes),
    }


# -----------------------------------------------------------------------------
# The checks in a fresh process (extension_check.py, legacy_check.py, the GUI checks)


def press_on_test_scene(out):
    """Build the test scene in the current file and press Build & Render;
    add what came of it to the report `out`. (Loading factory settings
    would also reset the preferences that enable an installed add-on.)"""
    scene = bpy.context.scene
    for obj in list(scene.objects):
        bpy.data.objects.remove(obj)
    build_test_scene(scene)
    out["operator"] = sorted(bpy.ops.bsplab.build_render())
    image = bpy.data.images.get("BSP Lab Preview")
    out["image_size"] = list(image.size) if image else None
    out["triangles"] = scene.bsplab.stats.get("scene", {}).get("triangles")
    return scene


def print_report_and_exit(tag, main, *args):
    """Print "TAG {json}" of main(*args)'s report (or of its exception, which
    the test then fails on) and exit without the bpy 4.2 module's crash in
    its exit-time destructors."""
    import json
    try:
        report = main(*args)
    except Exception as ex:
        report = {"error": "{}: {}".format(type(ex).__name__, ex)}
    print(tag + " " + json.dumps(report), flush=True)
    sys.stderr.flush()
    os._exit(0)


# The installed extension's module (Blender 4.2+, the "user_default" repository).
EXTENSION_MODULE = "bl_ext.user_default.bsplab"


def use_extension(zip_path):
    """The 4.2+ extension path: install the zip (its wheels bring the core)
    and enable it; load_addon() then answers the installed module."""
    result = bpy.ops.extensions.package_install_files(
        filepath=zip_path, repo="user_default", enable_on_install=True)
    assert result == {'FINISHED'}, result
    sys.modules[ADDON_MODULE] = importlib.import_module(EXTENSION_MODULE)


def start_gui_check(tick, report):
    """A GUI check's start: the add-on registered from the source tree with
    bsplab on the path, or with BSPLAB_GUI_EXTENSION_ZIP the extension zip
    installed and enabled (use_extension); then `tick` (the check's steps)
    on a timer, which runs once the window is up. No splash screen over the
    window: a --python script runs before Blender opens it, and the factory
    settings' preferences are not saved. The report says which add-on and
    which core the check ran."""
    bpy.context.preferences.view.show_splash = False
    zip_path = os.environ.get("BSPLAB_GUI_EXTENSION_ZIP")
    if zip_path:
        use_extension(zip_path)
    else:
        add_core_paths()
        load_addon().register()
    import bsplab
    report.update(addon=load_addon().__file__, core=bsplab.__file__)
    bpy.app.timers.register(tick, first_interval=0.1)


def reporting_failures(step, report, finish):
    """A GUI check's timer function: `step()` (its return value is the
    timer's next interval, None to stop); a failed step or a time-out ends
    the check through `finish()` with the traceback in report["error"]."""
    def tick():
        try:
            return step()
        except Exception:
            import traceback
            report["error"] = traceback.format_exc()
            finish()
            return None
    return tick


def script_args():
    """The arguments after Blender's "--": the script's own ([] without)."""
    return sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []


def gui_check_output(default_out, **report_lists):
    """A GUI check's output folder (its first argument, else `default_out`;
    made), the rest of its arguments, and its report: the Blender version,
    an "events" list and one empty list per name in `report_lists`."""
    args = script_args()
    out = pathlib.Path(args[0] if args else default_out)
    out.mkdir(parents=True, exist_ok=True)
    report = {"blender": bpy.app.version_string, **{k: [] for k in report_lists}, "events": []}
    return out, args[1:], report
