# SPDX-License-Identifier: GPL-3.0-or-later
"""The add-on's runtime state: one object, `STATE`, and its Blender handlers.

Everything the add-on holds between two clicks lives here and nowhere else:
the job running on its worker thread, the kept trees (the tree caches of
Build & Render's A and B), the last Build & Render shown (which the ray
inspector inspects and the overlay draws), the last inspection, the
overlay's geometry and GPU batches, the viewport draw handlers, and the
count of scene changes that may have moved the triangles.

The features read and write it; they keep no module-level state of their
own. That way one handler can forget all of a file's state when another is
loaded, and the features talk to each other through it instead of through
each other's internals: Build & Render records what it showed
(`shown_build`), the inspector and the overlay read that.

Handlers (added by the add-on's register(), removed by unregister()):
- load_pre: a tree, an inspection or an overlay of the previous file must
  never be shown for the next, nor hold its memory (`forget_file`);
- load_post: the features' `after_load` listeners (the overlay re-adds its
  draw handler when the loaded file has its tick box on);
- depsgraph_update_post: counts the updates that may change the scene's
  triangles (`scene_changes`), what tells a stale build from a fresh one.
"""

import collections
import functools

import bpy

# Object types whose updates never change the triangles a tree was built of.
NOT_GEOMETRY = frozenset({'CAMERA', 'LIGHT', 'LIGHT_PROBE', 'LIGHTPROBE', 'SPEAKER'})

# The viewport's draw handlers draw in world space, in the main region.
DRAW_REGION, DRAW_STAGE = 'WINDOW', 'POST_VIEW'

# How many of the overlay's last draw times are kept (the GUI check's
# per-frame figure; a deque append costs nothing next to a draw).
DRAW_TIMES_KEPT = 1000


class AddonState:
    """The add-on's runtime state (one instance: `STATE`)."""

    def __init__(self):
        self.registered = False
        # The one job in flight (a jobs.worker.WorkerJob), if any; the
        # panels read its progress and the operators refuse a second.
        self.job = None
        # The last Build & Render shown (a jobs.shown_build.ShownBuild), or None.
        self.shown_build = None
        # The last ray inspection (inspector.trace.inspect()), or None.
        self.inspection = None
        # Updates that may have changed the scene's triangles (see _may_change_triangles).
        self.scene_changes = 0
        # The viewport draw handlers by name ("overlay", "inspector").
        self.draw_handles = {}
        # The GPU batches of the overlay's geometry: (geometry, (shader, batches)).
        self.overlay_batches = (None, (None, ()))
        self.overlay_draw_seconds = collections.deque(maxlen=DRAW_TIMES_KEPT)
        self.overlay_draw_calls = 0
        # The GPU batches of the inspection they were made from: (inspection, layers).
        self.inspection_batches = (None, None)
        # Blender keeps only borrowed pointers to the strings of dynamic enum
        # items: the lists the callbacks return must stay referenced, by
        # enum name. Never forgotten while registered.
        self.enum_items = {}
        # Called after a file is loaded (the features add to it in register()).
        self.after_load = []

    # The caches are made on first use: their classes live in the features
    # (jobs/tree_cache.py, overlay/cache.py), which import this module.

    @functools.cached_property
    def tree_cache(self):
        """Build & Render's kept tree A (a jobs.tree_cache.TreeCache)."""
        from .jobs.tree_cache import TreeCache
        return TreeCache()

    @functools.cached_property
    def tree_cache_b(self):
        """Tree B of the A/B comparison, kept the same way."""
        from .jobs.tree_cache import TreeCache
        return TreeCache()

    @functools.cached_property
    def overlay_geometry(self):
        """The overlay's arrays (an overlay.cache.GeometryCache)."""
        from .overlay.cache import GeometryCache
        return GeometryCache()

    def kept_tree(self):
        """The tree the last Build & Render kept, or None."""
        return self.tree_cache.kept_tree()

    def forget_overlay(self):
        """Drop the overlay's geometry and batches (its tree is gone)."""
        self.overlay_geometry.clear()
        self.overlay_batches = (None, (None, ()))

    def forget_trees(self):
        """Forget the kept trees (and what running jobs would keep)."""
        self.tree_cache.clear()
        self.tree_cache_b.clear()

    def forget_file(self):
        """Forget everything made from the current file: the kept trees, the
        shown build, the inspection, the overlay's geometry."""
        self.forget_trees()
        self.shown_build = None
        self.inspection = None
        self.inspection_batches = (None, None)
        self.forget_overlay()

    def cancel_job(self):
        """Stop the running job (on unregister); waits a little for it."""
        if self.job is not None:
            self.job.cancel()
            self.job.join(5.0)
            self.job = None

    # -- the viewport's draw handlers ------------------------------------------

    def has_draw_handler(self, name):
        return name in self.draw_handles

    def add_draw_handler(self, name, function):
        """Add `function` as the SpaceView3D draw handler `name` (once)."""
        if name not in self.draw_handles:
            self.draw_handles[name] = bpy.types.SpaceView3D.draw_handler_add(
                function, (), DRAW_REGION, DRAW_STAGE)

    def remove_draw_handler(self, name):
        handle = self.draw_handles.pop(name, None)
        if handle is not None:
            bpy.types.SpaceView3D.draw_handler_remove(handle, DRAW_REGION)


STATE = AddonState()


def visible_objects(view_layer):
    """A fingerprint of which objects of the view layer are visible: hiding
    an object (`hide_set`, the outliner's eye) reaches the depsgraph handler
    only as an update of the scene, like a selection, so a build also keeps
    this and compares it (a pass over the objects, no extraction)."""
    return hash(tuple(obj.name for obj in view_layer.objects
                      if obj.visible_get(view_layer=view_layer)))


def scene_mark(view_layer):
    """What tells whether the scene changed since: (scene_changes, visible_objects)."""
    return STATE.scene_changes, visible_objects(view_layer)


def _may_change_triangles(update):
    data = update.id
    if isinstance(data, bpy.types.Object):
        return data.type not in NOT_GEOMETRY and (update.is_updated_geometry
                                                  or update.is_updated_transform)
    return isinstance(data, (bpy.types.Mesh, bpy.types.Collection))


@bpy.app.handlers.persistent
def count_scene_changes(_scene, depsgraph):
    """depsgraph_update_post handler. Counting is cheap; fingerprinting the
    triangles on every pick would cost an extraction of the scene. The count
    errs on the safe side: a relations update (e.g. after removing a
    data-block) flags the collections too."""
    if any(_may_change_triangles(update) for update in depsgraph.updates):
        STATE.scene_changes += 1


@bpy.app.handlers.persistent
def before_load(*_args):
    """load_pre handler: nothing of the previous file is shown for the next."""
    STATE.forget_file()


@bpy.app.handlers.persistent
def after_load(*_args):
    """load_post handler: the features' listeners."""
    for listener in STATE.after_load:
        listener()


HANDLERS = ((bpy.app.handlers.load_pre, before_load),
            (bpy.app.handlers.load_post, after_load),
            (bpy.app.handlers.depsgraph_update_post, count_scene_changes))


def add_handlers():
    for handlers, function in HANDLERS:
        if function not in handlers:
            handlers.append(function)


def remove_handlers():
    """Remove the handlers and forget the file's state (unregister)."""
    for handlers, function in HANDLERS:
        if function in handlers:
            handlers.remove(function)
    STATE.forget_file()
