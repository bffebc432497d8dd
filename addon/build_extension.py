#!/usr/bin/env python3
"""Build the installable BSP Lab extension zip into dist/.

    python addon/build_extension.py [--out-dir dist] [--core-wheel WHEEL]

Steps:
1. the `bsplab` wheel, built from core/ with `pip wheel ./core`;
2. `embreex`'s manylinux wheel for CPython 3.11 (Blender 4.2 - 5.0), from
   `pip download`;
3. a staging copy of addon/ with both under wheels/ and the manifest's
   `wheels = [...]` filled in;
4. `blender_ext.py build --split-platforms` (Blender's own extension tool,
   shipped inside the `bpy` pip package and runnable with plain Python)
   writes dist/bsplab-<version>-linux_x64.zip;
5. `blender_ext.py validate` checks the zip, with every copy of the tool
   found (bpy 4.2 and 5.0 when both venvs exist);
6. dist/bsplab_addon-<version>-legacy.zip, the same add-on as a legacy
   add-on for Blender 3.x-4.1 (no wheels: install the core separately).

Run it with the project's Python (the one that builds core/: it needs
scikit-build-core and nanobind for `--no-build-isolation`). Prints the zip's
path last.
"""

import argparse
import glob
import os
import pathlib
import re
import shutil
import subprocess
import sys
import zipfile

HERE = pathlib.Path(__file__).resolve().parent
REPO = HERE.parent
BUILD = REPO / "build" / "extension"
PYTHON_TAG = "3.11"  # Blender 4.2 LTS to 5.0 all embed CPython 3.11.
EMBREEX_PLATFORMS = ("manylinux_2_28_x86_64", "manylinux_2_17_x86_64", "manylinux2014_x86_64")
# Where blender_ext.py sits inside an installed bpy package.
BLENDER_EXT_GLOB = "bpy/*/scripts/addons_core/bl_pkg/cli/blender_ext.py"
# The bpy wheel to take blender_ext.py from when no bpy is installed anywhere.
FALLBACK_BPY = "bpy==4.2.23"
SOURCE_EXCLUDE = {"__pycache__", "build_extension.py", "demo_headless.py", "wheels"}


def log(message):
    print("build_extension: " + message, flush=True)


def run(cmd, **kwargs):
    log("$ " + " ".join(str(c) for c in cmd))
    subprocess.run([str(c) for c in cmd], check=True, **kwargs)


# -----------------------------------------------------------------------------
# Wheels


def newest_mtime(root):
    latest = 0.0
    for path in root.rglob("*"):
        if "build" in path.relative_to(root).parts[:1] or path.suffix in (".pyc", ".so"):
            continue
        if path.is_file():
            latest = max(latest, path.stat().st_mtime)
    return latest


def build_core_wheel(python, wheel_dir):
    """The bsplab wheel, rebuilt when core/ changed since the last one."""
    existing = sorted(wheel_dir.glob("bsplab-*.whl"), key=os.path.getmtime)
    if existing and existing[-1].stat().st_mtime >= newest_mtime(REPO / "core"):
        log("core wheel up to date: " + existing[-1].name)
        return existing[-1]
    for old in existing:
        old.unlink()
    cmd = [python, "-m", "pip", "wheel", REPO / "core", "--no-deps", "-w", wheel_dir]
    if can_build_without_isolation(python):
        cmd.append("--no-build-isolation")
    run(cmd)
    wheels = sorted(wheel_dir.glob("bsplab-*.whl"))
    if len(wheels) != 1:
        sys.exit("build_extension: expected one bsplab wheel in {}, found {}".format(wheel_dir, wheels))
    check_cp311(wheels[0])
    return wheels[0]


def can_build_without_isolation(python):
    probe = "import scikit_build_core, nanobind"
    return subprocess.run([python, "-c", probe], capture_output=True).returncode == 0


def check_cp311(wheel):
    if "-cp311-" not in wheel.name:
        sys.exit("build_extension: {} is not a CPython 3.11 wheel; Blender 4.2-5.0 need "
                 "cp311: run this script with a Python 3.11".format(wheel.name))


def embreex_version(python):
    """The embreex version the project uses, so the bundle matches the tests."""
    probe = "import importlib.metadata as m; print(m.version('embreex'))"
    result = subprocess.run([python, "-c", probe], capture_output=True, text=True)
    return result.stdout.strip() if result.returncode == 0 else None


def download_embreex(python, wheel_dir):
    existing = sorted(wheel_dir.glob("embreex-*.whl"))
    if existing:
        log("embreex wheel present: " + existing[-1].name)
        return existing[-1]
    version = embreex_version(python)
    spec = "embreex=={}".format(version) if version else "embreex"
    cmd = [python, "-m", "pip", "download", spec, "--no-deps", "--only-binary=:all:",
           "--python-version", PYTHON_TAG, "--implementation", "cp", "--abi", "cp311",
           "-d", wheel_dir]
    for platform in EMBREEX_PLATFORMS:
        cmd += ["--platform", platform]
    run(cmd)
    wheels = sorted(wheel_dir.glob("embreex-*.whl"))
    if not wheels:
        sys.exit("build_extension: pip download of embreex produced no wheel")
    return wheels[-1]


# -----------------------------------------------------------------------------
# Blender's extension tool


def find_blender_ext(python):
    """Every blender_ext.py of an installed bpy, newest Blender last."""
    roots = set(glob.glob(str(REPO / ".venv*" / "lib" / "python*" / "site-packages")))
    probe = "import site, sys; print('\\n'.join(site.getsitepackages() + sys.path))"
    result = subprocess.run([python, "-c", probe], capture_output=True, text=True)
    roots.update(p for p in result.stdout.splitlines() if p)
    if os.environ.get("BLENDER_EXT_PY"):
        found = {os.environ["BLENDER_EXT_PY"]}
    else:
        found = {f for root in roots for f in glob.glob(os.path.join(root, BLENDER_EXT_GLOB))}
    cached = REPO / "build" / "blender_ext" / "blender_ext.py"
    if not found and cached.exists():
        found = {str(cached)}
    if not found:
        found = {str(fetch_blender_ext(python, cached))}

    def version(path):
        match = re.search(r"bpy/(\d+)\.(\d+)/", path)
        return tuple(int(x) for x in match.groups()) if match else (0, 0)

    return sorted(found, key=version)


def fetch_blender_ext(python, target):
    """Take blender_ext.py out of a downloaded bpy wheel (no install)."""
    download = REPO / "build" / "bpy-wheel"
    run([python, "-m", "pip", "download", FALLBACK_BPY, "--no-deps", "--only-binary=:all:",
         "--python-version", PYTHON_TAG, "-d", download])
    wheel = next(download.glob("bpy-*.whl"))
    with zipfile.ZipFile(wheel) as archive:
        member = next(n for n in archive.namelist()
                      if n.endswith("scripts/addons_core/bl_pkg/cli/blender_ext.py"))
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(archive.read(member))
    shutil.rmtree(download)
    return target


# -----------------------------------------------------------------------------
# Staging and the zip


def stage(wheels):
    source = BUILD / "source"
    if source.exists():
        shutil.rmtree(source)
    shutil.copytree(HERE, source, ignore=lambda _d, names: [n for n in names if n in SOURCE_EXCLUDE
                                                           or n.endswith((".pyc", ".zip"))])
    (source / "wheels").mkdir()
    for wheel in wheels:
        shutil.copy2(wheel, source / "wheels" / wheel.name)
    manifest = source / "blender_manifest.toml"
    text = manifest.read_text()
    listing = "wheels = [\n{}]".format("".join(
        '  "./wheels/{}",\n'.format(w.name) for w in wheels))
    text, count = re.subn(r"^wheels = \[[^\]]*\]", listing, text, flags=re.MULTILINE)
    if count != 1:
        sys.exit("build_extension: no `wheels = [...]` line in the manifest to fill in")
    manifest.write_text(text)
    return source


def build_zip(python, blender_ext, source, out_dir):
    out_dir.mkdir(parents=True, exist_ok=True)
    before = set(out_dir.glob("*.zip"))
    for old in out_dir.glob("bsplab*.zip"):
        old.unlink()
    run([python, blender_ext, "build", "--source-dir", source, "--output-dir", out_dir,
         "--split-platforms"])
    zips = sorted(out_dir.glob("bsplab-*.zip"))  # not the legacy bsplab_addon-*
    if len(zips) != 1:
        sys.exit("build_extension: expected one zip in {}, found {} (before: {})".format(
            out_dir, zips, before))
    return zips[0]


def build_legacy_zip(out_dir):
    """A zip for Blender < 4.2 (Preferences > Add-ons > Install), no wheels.

    Its folder is `bsplab_addon`: a legacy add-on named `bsplab` would shadow
    the core module of the same name. The core must be installed into that
    Blender's Python separately.
    """
    version = re.search(r'^version = "([^"]+)"', (HERE / "blender_manifest.toml").read_text(),
                        re.MULTILINE).group(1)
    path = out_dir / "bsplab_addon-{}-legacy.zip".format(version)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        for source in sorted(HERE.glob("*.py")):
            if source.name not in SOURCE_EXCLUDE:
                archive.write(source, "bsplab_addon/" + source.name)
    log("built " + str(path))
    return path


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out-dir", type=pathlib.Path, default=REPO / "dist")
    parser.add_argument("--wheel-dir", type=pathlib.Path, default=REPO / "build" / "wheels",
                        help="where the wheels are built/downloaded (reused when up to date)")
    parser.add_argument("--core-wheel", type=pathlib.Path,
                        help="use this bsplab wheel instead of building one")
    parser.add_argument("--python", default=sys.executable,
                        help="the Python 3.11 that runs pip (default: this one)")
    args = parser.parse_args(argv)

    args.wheel_dir.mkdir(parents=True, exist_ok=True)
    core_wheel = args.core_wheel or build_core_wheel(args.python, args.wheel_dir)
    check_cp311(core_wheel)
    wheels = [core_wheel, download_embreex(args.python, args.wheel_dir)]
    tools = find_blender_ext(args.python)
    log("Blender extension tool(s): " + ", ".join(tools))
    source = stage(wheels)
    zip_path = build_zip(args.python, tools[-1], source, args.out_dir)
    for tool in tools:
        run([args.python, tool, "validate", zip_path])
    build_legacy_zip(args.out_dir)
    log("built " + str(zip_path))
    print(zip_path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
