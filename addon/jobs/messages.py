# SPDX-License-Identifier: GPL-3.0-or-later
"""What a press tells the user when the scene cannot be built or shown as
asked: the two-level build's refusals with the instance's object named, and
a render in which every camera ray missed. (A worker job's own errors, the
core's checks included, are worded in worker.error_message.)"""

from .worker import UserError

# Leaf culling has no two-level trace in the core (InstancedTree.intersect
# refuses cull=True).
TWO_LEVEL_CULL_MESSAGE = ("Leaf culling is not available for two-level builds: untick Leaf "
                          "Culling (and pick another mode than Heat Culled), or choose "
                          "Instances: Flatten")


def instance_message(message, geometry):
    """The core's refusal of an instance ("instance N: its matrix is
    singular ...") with the instance's object named, for the user."""
    head, sep, rest = message.partition(": ")
    words = head.split()
    if sep and len(words) == 2 and words[0] == "instance" and words[1].isdigit():
        index = int(words[1])
        names = geometry.instance_names if geometry is not None else []
        name = names[index] if index < len(names) else "#{}".format(index)
        hint = (" (an object scaled to 0 on an axis?): give it a non-zero scale, or choose "
                "Instances: Flatten") if "singular" in rest else ""
        return "BSP Lab cannot build the two-level scene: the instance of {}: {}{}".format(
            name, rest, hint)
    return "BSP Lab cannot build the two-level scene: {}".format(message)


def check_result(result):
    """Refuse a finished render in which every camera ray missed."""
    hits = result["stats"]["render"].get("hits")
    if hits == 0:
        raise UserError("No mesh in the camera's view: every camera ray missed")
