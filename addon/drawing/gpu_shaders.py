# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender's built-in GPU shaders by one name across versions.

Blender 4.0 dropped the "3D_" prefix of the built-in shader names that 3.x
used ("3D_UNIFORM_COLOR" became "UNIFORM_COLOR"); 3.4 knows the prefixed
names (and some unprefixed ones). Asking for the new name first and the old
one second works on 3.4 through 5.0. Import only where drawing happens: the
`gpu` module raises in background mode as soon as a shader is made.
"""

import functools

import gpu


@functools.lru_cache(maxsize=None)
def builtin(name):
    """The built-in shader `name` ("UNIFORM_COLOR", "SMOOTH_COLOR",
    "POLYLINE_UNIFORM_COLOR", "POLYLINE_SMOOTH_COLOR"), under whichever of
    its two names this Blender knows."""
    try:
        return gpu.shader.from_builtin(name)
    except ValueError:
        return gpu.shader.from_builtin("3D_" + name)
