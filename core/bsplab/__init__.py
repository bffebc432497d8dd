"""BSP Lab: build, trace and compare kd and BSP ray-tracing acceleration
structures. See docs/api.md for the API."""

from . import _core, oracle
from ._core import Cancelled
from .camera import Camera
from .checks import triangles as check_triangles
from .cpu import cpu_features
from .method_table import methods, option_schema
from .progress import Progress
from .render import RENDER_MODES, render
from .tree import Tree, build
from .instanced import InstancedTree, build_instanced, check_instance_matrices

__version__ = "0.1.0"
__all__ = ["Camera", "Cancelled", "InstancedTree", "Progress", "RENDER_MODES", "Tree", "build",
           "build_instanced", "check_instance_matrices",
           "check_triangles", "cpu_features", "methods", "option_schema", "oracle", "render", "_core"]
