"""The extension zip: valid for Blender's own tool, installs headless, works.

The zip comes from addon/tools/build_extension.py (run_all.sh builds it first);
BSPLAB_EXTENSION_ZIP may name another one.
"""

import json
import os
import pathlib
import subprocess
import sys
import zipfile

import bpy
import pytest

import bsplab_test_utils as utils
from conftest import in_bpy_module, require

HERE = pathlib.Path(__file__).resolve().parent

needs_extensions = pytest.mark.skipif(
    bpy.app.version < (4, 2, 0),
    reason="Blender {} predates extensions (4.2): the add-on installs there as a legacy "
           "add-on through bl_info".format(bpy.app.version_string))


def extension_zip():
    path = os.environ.get("BSPLAB_EXTENSION_ZIP")
    if not path:
        zips = sorted((utils.REPO / "dist").glob("bsplab-*.zip"), key=os.path.getmtime)
        path = str(zips[-1]) if zips else None
    require(path is not None and os.path.exists(path),
            "no extension zip: run addon/tools/build_extension.py first")
    sources = [p for p in utils.ADDON_DIR.glob("*") if p.suffix in (".py", ".toml")]
    newest = max(p.stat().st_mtime for p in sources)
    require(os.path.getmtime(path) >= newest,
            "{} is older than the add-on's sources: rebuild it".format(path))
    return path


def legacy_zip():
    zips = sorted((utils.REPO / "dist").glob("bsplab_addon-*-legacy.zip"), key=os.path.getmtime)
    require(bool(zips), "no legacy add-on zip: run addon/tools/build_extension.py first")
    return str(zips[-1])


def run_check(script, zip_path, env):
    """Run a check script in a fresh Blender process; return its JSON report."""
    script = str(HERE / script)
    if in_bpy_module():
        cmd = [sys.executable, script, zip_path]
    else:
        cmd = [bpy.app.binary_path, "--background", "--factory-startup", "-noaudio",
               "--python", script, "--", zip_path]
    result = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=600)
    tag = script.rsplit("/", 1)[-1].replace(".py", "").upper() + " "
    lines = [l for l in result.stdout.splitlines() if l.startswith(tag)]
    assert lines, result.stdout + result.stderr
    report = json.loads(lines[-1].split(" ", 1)[1])
    assert "error" not in report, report
    return report


def blender_ext_tool():
    return os.path.join(bpy.utils.system_resource('SCRIPTS'),
                        "addons_core", "bl_pkg", "cli", "blender_ext.py")


def test_zip_contents():
    tomllib = pytest.importorskip("tomllib")
    with zipfile.ZipFile(extension_zip()) as archive:
        names = archive.namelist()
        manifest = tomllib.loads(archive.read("blender_manifest.toml").decode())
    # Every module of the shipped folder, in its subpackage, and no tool or test.
    shipped = utils.shipped_modules()
    assert {"__init__.py", "state.py", "build_render/operator.py"} <= shipped
    assert shipped <= set(names), sorted(shipped - set(names))
    assert not [name for name in names if "__pycache__" in name or name.endswith(".pyc")]
    assert not [name for name in names if name.endswith(("build_extension.py", "demo_headless.py"))]
    assert not [name for name in names if name.split("/")[0] in utils.NOT_SHIPPED]
    wheels = manifest["wheels"]
    for wheel in wheels:
        assert wheel.lstrip("./") in names
    # Blender 4.2 - 5.0 embed CPython 3.11, 5.1 - 5.2 CPython 3.13: the core
    # for each (3.13's through the stable ABI) and embreex for each.
    tags = sorted(wheel_tags(w) for w in wheels)
    assert tags == [("bsplab", "cp311-cp311"), ("bsplab", "cp312-abi3"),
                    ("embreex", "cp311-cp311"), ("embreex", "cp313-cp313")], tags
    assert manifest["blender_version_min"] == "4.2.0"
    assert manifest["blender_version_max"] == "5.3.0"


def test_legacy_zip_contents():
    """The legacy add-on: the same modules, with their subpackages, under bsplab_addon/."""
    with zipfile.ZipFile(legacy_zip()) as archive:
        names = set(archive.namelist())
    shipped = {"bsplab_addon/" + name for name in utils.shipped_modules()}
    assert names == shipped, sorted(names ^ shipped)


def wheel_tags(wheel):
    """("bsplab", "cp311-cp311") from ./wheels/bsplab-0.1.0-cp311-cp311-linux_x86_64.whl."""
    parts = pathlib.Path(wheel).name.split("-")
    return parts[0], "-".join(parts[-3:-1])


@needs_extensions
def test_blender_takes_its_pythons_wheels():
    """Blender's own wheel filter keeps one core and one embreex for this Python."""
    bl_extension_ops = pytest.importorskip("bl_pkg.bl_extension_ops")
    tomllib = pytest.importorskip("tomllib")
    with zipfile.ZipFile(extension_zip()) as archive:
        wheels = tomllib.loads(archive.read("blender_manifest.toml").decode())["wheels"]
    kept = bl_extension_ops._extensions_wheel_filter_for_this_system(wheels)
    assert sorted(wheel_tags(w)[0] for w in kept) == ["bsplab", "embreex"], kept


@needs_extensions
@pytest.mark.parametrize("target", ["zip", "source"])
def test_blender_validates(target):
    tool = blender_ext_tool()
    assert os.path.exists(tool), tool
    path = extension_zip() if target == "zip" else str(utils.ADDON_DIR)
    # The tool runs with plain Python; Blender's own is sys.executable.
    result = subprocess.run([sys.executable, tool, "validate", path],
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "Success" in result.stdout


@needs_extensions
def test_zip_installs_headless_and_runs(tmp_path):
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "user"))
    # bsplab must come from the zip's wheels, nowhere else.
    for name in ("PYTHONPATH", "BSPLAB_PYTHONPATH"):
        env.pop(name, None)
    report = run_check("extension_check.py", extension_zip(), env)
    assert report["install"] == ["FINISHED"]
    assert "bl_ext.user_default.bsplab" in report["addons"]
    if report["core_before_install"] is None:
        assert "/extensions/" in report["core"], report["core"]
    assert report["operator"] == ["FINISHED"]
    assert report["image_size"] == [80, 60]
    assert report["triangles"] == utils.EXPECTED_TRIANGLES
    clash = report["foreign_embree"]
    if clash is not None:
        # As test_operator.py's test_compare_with_embree: declined, by name.
        assert not report["embree"]["available"] and clash in report["embree"]["message"]
        return
    assert report["embree"]["available"], report["embree"]
    assert report["embree"]["compare"]["agreement"] >= 0.999


def test_legacy_zip_installs_headless_and_runs(tmp_path):
    """The bl_info route, for Blender before 4.2 (and still supported after)."""
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "user"),
               BLENDER_USER_SCRIPTS=str(tmp_path / "scripts"))
    report = run_check("legacy_check.py", legacy_zip(), env)
    assert report["install"] == ["FINISHED"]
    assert report["enabled"]
    assert str(tmp_path / "scripts") in report["module_file"]
    assert report["operator"] == ["FINISHED"]
    assert report["image_size"] == [80, 60]
    assert report["triangles"] == utils.EXPECTED_TRIANGLES
    assert report["unregistered"]
