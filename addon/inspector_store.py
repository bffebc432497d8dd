# SPDX-License-Identifier: GPL-3.0-or-later
"""What the ray inspector keeps: the last Build & Render it can inspect, and
the last inspection.

Build & Render tells this module when it makes its job (`build_started`)
and when it has shown the preview (`remember_build`). The record holds the
camera the preview was traced with, so a preview pixel gives back exactly
that pixel's ray even after the scene camera moved, and only a weak
reference to the tree: the tree cache (tree_cache.py) owns the tree and
holds one at a time, and the inspector must not keep an old one alive next
to a new one. It does keep the scene's triangles of that build (12 MB on
conference's 331k triangles) to draw the tested ones from.

Staleness: a depsgraph_update_post handler counts the updates that can
change the scene's triangles (geometry or transform of anything but
cameras and lights, and any mesh or collection change). Counting is cheap;
fingerprinting the triangles on every pick would cost an extraction of the
scene. A build whose count moved between its start and the pick is stale.
The count errs on the safe side: a relations update (e.g. after removing a
data-block) flags the collections too, and then the user is asked to press
Build & Render again, which re-uses the tree when the triangles are the same.
Hiding an object in the view layer (`hide_set`, the outliner's eye) reaches
the handler only as an update of the scene, like a selection: so the build
also keeps which objects were visible, compared on each pick (a pass over
the view layer's objects, no extraction).
"""

from dataclasses import dataclass

import bpy

# Object types whose updates never change the triangles the tree was built of.
NOT_GEOMETRY = frozenset({'CAMERA', 'LIGHT', 'LIGHT_PROBE', 'LIGHTPROBE', 'SPEAKER'})

_changes = 0  # updates that may have changed the scene's triangles
_build = None  # the KeptBuild of the last Build & Render, or None
_inspection = None  # the last inspection (inspector_trace.inspect()), or None


@dataclass
class KeptBuild:
    """The last Build & Render as the inspector needs it."""

    tree_ref: object  # weakref.ref to the bsplab.Tree (the tree cache owns it)
    # Tree B of an A/B press whose preview is split (B's render right of the
    # line), weakly; None otherwise (a difference map is picked as A's).
    split_b_ref: object
    # The scene's (N, 3, 3) triangles the tree was built of, in world units:
    # the tested triangles are drawn from them. Tree.triangles would give the
    # same numbers but copies the whole array when the tree scaled its
    # coordinates (28 ms on conference's 331k triangles, per click).
    triangles: object
    camera: object  # the job's CameraSpec (kwargs(), width, height, name)
    cull: bool  # whether the preview was traced with leaf culling
    scene_name: str
    image_size: tuple  # the preview image block's (width, height), colour bar included
    changes: int  # _changes when the job read the scene
    visible: int  # visible_objects() then

    def tree(self):
        return self.tree_ref()

    def split_b(self):
        """Tree B when the preview is split (None if not, or B is gone)."""
        return None if self.split_b_ref is None else self.split_b_ref()

    @property
    def render_size(self):
        return self.camera.width, self.camera.height


def scene_changes():
    return _changes


def visible_objects(view_layer):
    """A fingerprint of which objects of the view layer are visible."""
    return hash(tuple(obj.name for obj in view_layer.objects
                      if obj.visible_get(view_layer=view_layer)))


def _may_change_triangles(update):
    data = update.id
    if isinstance(data, bpy.types.Object):
        return data.type not in NOT_GEOMETRY and (update.is_updated_geometry
                                                  or update.is_updated_transform)
    return isinstance(data, (bpy.types.Mesh, bpy.types.Collection))


@bpy.app.handlers.persistent
def count_scene_changes(_scene, depsgraph):
    """depsgraph_update_post handler."""
    global _changes
    if any(_may_change_triangles(update) for update in depsgraph.updates):
        _changes += 1


@bpy.app.handlers.persistent
def forget(*_args):
    """load_pre handler (and unregister): nothing of another file is inspected."""
    global _build, _inspection
    _build = _inspection = None


def add_handlers():
    if count_scene_changes not in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.append(count_scene_changes)
    if forget not in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.append(forget)


def remove_handlers():
    if count_scene_changes in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.remove(count_scene_changes)
    if forget in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.remove(forget)
    forget()


def build_started(job, view_layer):
    """Build & Render made `job` from the scene as it is now."""
    job.inspector_mark = (_changes, visible_objects(view_layer))


def remember_build(scene, job, image):
    """Build & Render showed `job`'s result in the preview image block `image`."""
    global _build
    tree_ref = job.a.tree_ref
    if tree_ref is None or tree_ref() is None:
        _build = None
        return
    inp = job.input
    split = job.b is not None and inp.compare_view == "split"
    _build = KeptBuild(
        tree_ref=tree_ref, split_b_ref=job.b.tree_ref if split else None,
        triangles=inp.triangles, camera=inp.camera,
        cull=bool(inp.cull or inp.mode == "heat_culled"), scene_name=scene.name,
        image_size=tuple(image.size),
        changes=job.inspector_mark[0], visible=job.inspector_mark[1])


def kept_build():
    return _build


def is_stale(build, view_layer):
    """Whether the scene may have changed since `build` read it."""
    return build.changes != _changes or build.visible != visible_objects(view_layer)


def keep_inspection(inspection):
    global _inspection
    _inspection = inspection


def inspection():
    return _inspection
