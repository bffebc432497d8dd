# SPDX-License-Identifier: GPL-3.0-or-later
"""The record of the last Build & Render whose preview is shown
(`STATE.shown_build`), for the features that work on it: the ray inspector
traces its tree, and could not tell a preview pixel's ray without it.

The build operator marks the scene when it makes its job (`mark_job`) and
records the build once the preview shows it (`record`); it knows nothing
of who reads the record.

The record holds the camera the preview was traced with, so a preview pixel
gives back exactly that pixel's ray even after the scene camera moved, and
only a weak reference to the tree: the tree cache (tree_cache.py) owns the
tree and holds one at a time, and the record must not keep an old one
alive next to a new one. It does keep the scene's triangles of that build
(12 MB on conference's 331k triangles) to draw the tested ones from.

Staleness: the state's change counter (state.py) and the visible objects
when the job read the scene, against the same now. A stale build asks the
user to press Build & Render again, which re-uses the tree when the
triangles are the same.
"""

from dataclasses import dataclass

from .. import state
from ..state import STATE


@dataclass
class ShownBuild:
    """The last Build & Render as its preview shows it."""

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
    changes: int  # STATE.scene_changes when the job read the scene
    visible: int  # state.visible_objects() then
    # A two-level build's names, for the overlay and the inspector to say
    # which instance they show: per instance its object ("'Prop Cube' in
    # 'Grid 1 1'"), per unique mesh its object's name; empty for a flat build.
    instance_names: tuple = ()
    mesh_names: tuple = ()

    def tree(self):
        return self.tree_ref()

    def split_b(self):
        """Tree B when the preview is split (None if not, or B is gone)."""
        return None if self.split_b_ref is None else self.split_b_ref()

    @property
    def render_size(self):
        return self.camera.width, self.camera.height


def mark_job(job, view_layer):
    """Build & Render made `job` from the scene as it is now."""
    job.scene_mark = state.scene_mark(view_layer)


def record(scene, job, image):
    """Build & Render showed `job`'s result in the preview image block `image`."""
    tree_ref = job.a.tree_ref
    if tree_ref is None or tree_ref() is None:
        STATE.shown_build = None
        return
    inp = job.input
    split = job.b is not None and inp.compare_view == "split"
    STATE.shown_build = ShownBuild(
        tree_ref=tree_ref, split_b_ref=job.b.tree_ref if split else None,
        triangles=inp.triangles, camera=inp.camera,
        cull=bool(inp.cull or inp.mode == "heat_culled"), scene_name=scene.name,
        image_size=tuple(image.size),
        changes=job.scene_mark[0], visible=job.scene_mark[1],
        instance_names=tuple(inp.instanced.instance_names) if inp.instanced else (),
        mesh_names=tuple(inp.instanced.mesh_names) if inp.instanced else ())


def names_of(tree):
    """(instance names, mesh names) of the shown build when `tree` is its
    tree (A or split B: the same scene's instances), else ((), ())."""
    build = STATE.shown_build
    if build is None or tree is None or (build.tree() is not tree and build.split_b() is not tree):
        return (), ()
    return build.instance_names, build.mesh_names


def is_stale(build, view_layer):
    """Whether the scene may have changed since `build` read it."""
    return (build.changes, build.visible) != state.scene_mark(view_layer)


def instance_text(instance, mesh, names=None):
    """How the panel names an instance: "instance 4 'Grid 1 1' (mesh 'Prop
    Cube')" with the names of the build (shown_build's), else by numbers."""
    instance_names, mesh_names = names or ((), ())
    text = "instance {}".format(instance)
    if 0 <= instance < len(instance_names):
        text += " {}".format(instance_names[instance])
    if 0 <= mesh < len(mesh_names):
        return text + " (mesh '{}')".format(mesh_names[mesh])
    return text + (" (mesh {})".format(mesh) if mesh >= 0 else "")
