"""The Blender side of BSP Lab: reading a scene out of Blender's data.

`extract.scene_triangles` (the evaluated scene's world-space triangles) and
`scene_camera.scene_camera` (the scene camera as `bsplab.Camera` parameters) take
bpy objects but never import bpy, so `import bsplab.blender` works anywhere;
they need only numpy and are written to run as plain modules too, because
`export_scene.py` (a script Blender runs for `bsplab.io.load_blend`) loads
them from this folder in a Blender whose Python may not load the compiled
core. The add-on uses the same modules, so an experiment on a .blend sees
exactly the triangles and camera that Build & Render sees.
"""

from pathlib import Path

# Run as `blender -b FILE.blend --python EXPORT_SCRIPT -- OUT.npz`.
EXPORT_SCRIPT = Path(__file__).with_name("export_scene.py")
