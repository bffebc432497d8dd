# SPDX-License-Identifier: GPL-3.0-or-later
"""The evaluated scene's triangles: flat (world space) or instanced (one
mesh per evaluated mesh datablock, in object space, and its instances).

Reads the evaluated dependency graph, so modifiers, geometry nodes and
instances (collection instances, instanced faces/vertices, geometry-node
instances) are included exactly as Blender renders them. Objects the
depsgraph does not iterate (hidden in the viewport, disabled collections)
are left out.

Every object Blender renders as a surface is read: meshes, and the curves
with a bevel or an extrusion, text, NURBS surfaces and metaballs, which
the depsgraph evaluates to meshes. Blender 3.0+ hands those meshes out as
instances of type 'MESH' whose original is the curve (text, surface,
metaball) object, next to the curve object itself; a curve object whose
mesh did not come as such an instance (metaballs before Blender 3.5) is
converted with `to_mesh()` instead. A curve without bevel or extrusion, an
empty text, a metaball of a family whose basis is another object: no
faces, nothing.

Two instances share one mesh when their evaluated object's data is the
same evaluated mesh: linked duplicates without modifiers, the objects of a
collection instanced several times, geometry-node instances of one
geometry. An object with modifiers has a mesh of its own.

Takes bpy objects, imports neither bpy nor the rest of bsplab (see
bsplab/blender/__init__.py for why).
"""

from dataclasses import dataclass, field

import numpy as np

# Object types whose evaluated geometry can be a surface.
SURFACE_TYPES = frozenset({'MESH', 'CURVE', 'SURFACE', 'FONT', 'META'})


@dataclass
class SceneGeometry:
    triangles: np.ndarray  # (N, 3, 3) float32, world space
    objects: int  # distinct objects that contributed (meshes, curves, text, ...)
    instances: int  # mesh occurrences (objects + instances)

    @property
    def triangle_count(self):
        return len(self.triangles)


@dataclass
class InstancedGeometry:
    """The scene as unique meshes and their instances."""

    # Per unique mesh with faces: (n, 3, 3) float32 object-space triangles.
    meshes: list
    # Per instance of a mesh with faces: its mesh's index (M,) int64 and its
    # world-from-object matrix (M, 3, 4) float64.
    mesh_index: np.ndarray
    matrices: np.ndarray
    # Per instance, the object it shows ("'Cube'", or "'Cube' in 'Grid'"
    # for an instance made by another object): for messages.
    instance_names: list
    # Per unique mesh, the object it was first read from (messages, panel).
    mesh_names: list
    objects: int  # as SceneGeometry's
    instances: int  # every mesh occurrence, those without faces included
    # Triangles the flattened scene holds (sum over the instances).
    triangle_count: int = 0
    mesh_triangle_count: int = field(default=0)

    def flatten(self):
        """The (T, 3, 3) float32 world triangles: instances in order, each
        mesh's triangles in order (what scene_triangles() gives for the
        same depsgraph, and bsplab.InstancedTree.flatten()'s order)."""
        parts = [_to_world(self.meshes[i].astype(np.float64), m)
                 for i, m in zip(self.mesh_index, self.matrices)]
        if not parts:
            return np.zeros((0, 3, 3), np.float32)
        return np.concatenate(parts).astype(np.float32)


def is_surface_instance(inst):
    """True for an instance carrying an evaluated mesh (of a mesh, curve,
    text, surface or metaball object) that is drawn: `show_self` is False
    for instancers whose own geometry is not drawn (e.g. a mesh instancing
    its vertices)."""
    return inst.object.type == 'MESH' and inst.show_self


def is_mesh_instance(inst):
    """True for mesh geometry of a mesh object, instanced or not (the rule
    before curves, text, surfaces and metaballs were read)."""
    return is_surface_instance(inst) and inst.object.original.type == 'MESH'


def _local_triangles(obj):
    """(n, 3, 3) float32 object-space triangles of an evaluated object."""
    # `to_mesh()` also resolves meshes whose subdivision would otherwise be
    # evaluated on the GPU only.
    try:
        mesh = obj.to_mesh()
    except RuntimeError:
        # "Object does not have geometry data": e.g. a text without characters.
        return np.zeros((0, 3, 3), np.float32)
    try:
        if mesh is None:
            return np.zeros((0, 3, 3), np.float32)
        mesh.calc_loop_triangles()
        n_verts = len(mesh.vertices)
        n_tris = len(mesh.loop_triangles)
        if n_tris == 0:
            return np.zeros((0, 3, 3), np.float32)
        verts = np.empty(n_verts * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", verts)
        tris = np.empty(n_tris * 3, dtype=np.int32)
        mesh.loop_triangles.foreach_get("vertices", tris)
        return verts.reshape(-1, 3)[tris.reshape(-1, 3)]
    finally:
        obj.to_mesh_clear()


def _matrix_3x4(matrix):
    return np.array(matrix, dtype=np.float64)[:3, :4]


def _to_world(local, m):
    """Object-space triangles (float64) to world space by a 3 x 4 matrix."""
    return local @ m[:, :3].T + m[:, 3]


def _instance_name(inst):
    obj = inst.object.original
    parent = inst.parent.original if inst.is_instance and inst.parent is not None else None
    if parent is None or parent == obj:
        return "'{}'".format(obj.name)
    return "'{}' in '{}'".format(obj.name, parent.name)


def surface_instances(depsgraph):
    """Yields (key, evaluated object, 3 x 4 float64 matrix, instance name,
    original object name, whether the original is a mesh object) for every
    drawn surface of the evaluated scene, in the depsgraph's order. Equal
    keys: the same evaluated mesh. A generator: an instance's object (a
    temporary one for collection and geometry-node instances) can be read
    (`to_mesh()`) only before the next item is asked for."""
    # Curve-like objects (by original) whose mesh came as an instance, and
    # those seen themselves: the latter without the former are converted.
    meshed, curves = set(), []
    for inst in depsgraph.object_instances:
        obj = inst.object
        if is_surface_instance(inst):
            original = obj.original
            if original.type != 'MESH':
                meshed.add(original.as_pointer())
            # The instance's matrix is only valid during this iteration step.
            yield (obj.data.as_pointer(), obj, _matrix_3x4(inst.matrix_world),
                   _instance_name(inst), original.name, original.type == 'MESH')
        elif obj.type in SURFACE_TYPES and not inst.is_instance and inst.show_self:
            # A curve, text, surface or metaball object itself (not an
            # instance: its evaluated object outlives the iteration).
            curves.append((obj, _matrix_3x4(inst.matrix_world)))
    for obj, matrix in curves:
        if obj.type == 'FONT' and not obj.data.body:
            continue  # no characters: no geometry (to_mesh() would refuse it)
        if obj.original.as_pointer() not in meshed:
            yield (("object", obj.original.as_pointer()), obj, matrix,
                   "'{}'".format(obj.original.name), obj.original.name, False)


def scene_instances(depsgraph):
    """The scene as unique meshes in object space and their instances
    (InstancedGeometry). Mesh objects without faces count as objects and
    instances but get no entry; a curve, text, surface or metaball without
    faces is not counted (it is not drawn as a surface)."""
    meshes, mesh_names, slots = [], [], {}
    mesh_index, matrices, names = [], [], []
    objects = set()
    instances = 0
    empty = set()
    for key, obj, matrix, name, original, is_mesh in surface_instances(depsgraph):
        if key not in slots and key not in empty:
            local = _local_triangles(obj)
            if len(local):
                slots[key] = len(meshes)
                meshes.append(local)
                mesh_names.append(original)
            else:
                empty.add(key)
        if key in empty and not is_mesh:
            continue
        # "Empty mesh" is not "no mesh": a mesh object without faces is
        # counted, not kept.
        objects.add(original)
        instances += 1
        if key in slots:
            mesh_index.append(slots[key])
            matrices.append(matrix)
            names.append(name)
    mesh_index = np.array(mesh_index, dtype=np.int64)
    sizes = np.array([len(m) for m in meshes], dtype=np.int64)
    return InstancedGeometry(
        meshes=meshes, mesh_index=mesh_index,
        matrices=np.array(matrices, dtype=np.float64).reshape(-1, 3, 4),
        instance_names=names, mesh_names=mesh_names, objects=len(objects),
        instances=instances,
        triangle_count=int(sizes[mesh_index].sum()) if len(mesh_index) else 0,
        mesh_triangle_count=int(sizes.sum()))


def scene_triangles(depsgraph):
    """Collect the world-space triangles of every drawn surface instance."""
    geometry = scene_instances(depsgraph)
    return SceneGeometry(triangles=geometry.flatten(), objects=geometry.objects,
                         instances=geometry.instances)
