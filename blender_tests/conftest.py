"""pytest setup for the add-on tests.

Runs in-process with the `bpy` pip package (one pytest process per bpy
version: bpy can be imported once per process) or inside a Blender binary
through run_in_blender.py. BSPLAB_STRICT=1 (set by run_all.sh) turns the
"core not importable" and "no extension zip" skips into failures, so a
broken install cannot pass as skipped.
"""

import os
import sys
import tempfile

# Keep Blender's user files (preferences, installed extensions) out of the
# home directory. Must be set before bpy is first imported; inside a Blender
# binary bpy is already there and the runner sets it instead.
if "bpy" not in sys.modules:
    os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="bsplab-user-"))

import pytest

import bpy  # noqa: E402
import bsplab_test_utils as utils  # noqa: E402

STRICT = os.environ.get("BSPLAB_STRICT") == "1"

utils.add_core_paths()


def pytest_report_header(config):
    return "Blender {} ({}), Python {}".format(
        bpy.app.version_string, bpy.app.binary_path or "bpy module", sys.version.split()[0])


def require(condition, reason):
    """Skip when not strict, fail when strict."""
    if condition:
        return
    if STRICT:
        pytest.fail(reason + " (BSPLAB_STRICT=1)")
    pytest.skip(reason)


@pytest.fixture(scope="session")
def addon():
    module = utils.load_addon()
    module.register()
    yield module
    module.unregister()


@pytest.fixture(scope="session")
def core():
    try:
        import bsplab
    except ImportError as ex:
        require(False, "the bsplab core is not importable: {}".format(ex))
    return bsplab


@pytest.fixture
def empty_scene(addon):
    return utils.reset_file()


@pytest.fixture
def test_scene(addon):
    scene = utils.reset_file()
    objects = utils.build_test_scene(scene)
    objects["scene"] = scene
    return objects


def in_bpy_module():
    """True under the `bpy` pip package, False inside a Blender binary."""
    return not bpy.app.binary_path


_exit_status = [0]


def pytest_sessionfinish(session, exitstatus):
    _exit_status[0] = int(exitstatus)


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config):
    # The bpy 4.2 module crashes in C++ static destructors at process exit
    # once a class with a Python callback was registered (bpy_class_free
    # takes the GIL after Python was finalised). The suite's verdict is known
    # by now; leave before those destructors run so the exit code is pytest's.
    if in_bpy_module() and bpy.app.version < (5, 0, 0):
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(_exit_status[0])
