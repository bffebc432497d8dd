"""The mesh file formats behind `bsplab.io`: `ply.py` and `obj.py` (bsplab's
own strict readers, and the PLY writer), `via_trimesh.py` (glTF/GLB, STL, OFF
through trimesh) and `checks.py` (what every reader's result must satisfy)."""
