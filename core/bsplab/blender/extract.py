# SPDX-License-Identifier: GPL-3.0-or-later
"""World-space triangles of the evaluated scene.

Reads the evaluated dependency graph, so modifiers, geometry nodes and
instances (collection instances, instanced faces/vertices, geometry-node
instances) are included exactly as Blender renders them. Objects the
depsgraph does not iterate (hidden in the viewport, disabled collections)
are left out, and so is every object that is not a mesh (curves and text
included, although Blender evaluates them to meshes).

Takes bpy objects, imports neither bpy nor the rest of bsplab (see
bsplab/blender/__init__.py for why).
"""

from dataclasses import dataclass

import numpy as np


@dataclass
class SceneGeometry:
    triangles: np.ndarray  # (N, 3, 3) float32, world space
    objects: int  # distinct mesh objects that contributed
    instances: int  # mesh occurrences (objects + instances)

    @property
    def triangle_count(self):
        return len(self.triangles)


def is_mesh_instance(inst):
    """True for mesh geometry of a mesh object, instanced or not.

    Curves and text evaluate to meshes too, but their instances point back at
    the non-mesh original; `show_self` is False for instancers whose own
    geometry is not drawn (e.g. a mesh instancing its vertices).
    """
    obj = inst.object
    return obj.type == 'MESH' and obj.original.type == 'MESH' and inst.show_self


def _local_triangles(obj):
    """(n, 3, 3) float64 object-space triangles of an evaluated mesh object."""
    # `to_mesh()` also resolves meshes whose subdivision would otherwise be
    # evaluated on the GPU only.
    mesh = obj.to_mesh()
    try:
        if mesh is None:
            return np.zeros((0, 3, 3))
        mesh.calc_loop_triangles()
        n_verts = len(mesh.vertices)
        n_tris = len(mesh.loop_triangles)
        if n_tris == 0:
            return np.zeros((0, 3, 3))
        verts = np.empty(n_verts * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", verts)
        tris = np.empty(n_tris * 3, dtype=np.int32)
        mesh.loop_triangles.foreach_get("vertices", tris)
        return verts.reshape(-1, 3).astype(np.float64)[tris.reshape(-1, 3)]
    finally:
        obj.to_mesh_clear()


def _to_world(local, matrix):
    m = np.array(matrix, dtype=np.float64)
    return local @ m[:3, :3].T + m[:3, 3]


def scene_triangles(depsgraph):
    """Collect the world-space triangles of every visible mesh instance."""
    chunks = []
    objects = set()
    instances = 0
    # Instances of one object share one evaluated mesh: read it once. Keyed
    # by the original object too, because unmodified objects sharing a mesh
    # datablock share the evaluated mesh pointer as well.
    cache = {}
    for inst in depsgraph.object_instances:
        obj = inst.object
        if not is_mesh_instance(inst):
            continue
        key = (obj.original.as_pointer(), obj.data.as_pointer() if obj.data else 0)
        local = cache.get(key)
        if local is None:
            local = cache[key] = _local_triangles(obj)
        # Meshes without faces count too: "empty mesh" is not "no mesh".
        objects.add(obj.original.name)
        instances += 1
        if len(local) == 0:
            continue
        # The instance's matrix is only valid during this iteration step.
        chunks.append(_to_world(local, inst.matrix_world))
    if chunks:
        triangles = np.concatenate(chunks).astype(np.float32)
    else:
        triangles = np.zeros((0, 3, 3), dtype=np.float32)
    return SceneGeometry(triangles=triangles, objects=len(objects), instances=instances)

