#!/usr/bin/env python3
"""Build the installable BSP Lab extension zip into dist/.

    python addon/tools/build_extension.py --python313 PYTHON3.13 [--out-dir dist]

Blender 4.2 - 5.0 embed CPython 3.11 and Blender 5.1 - 5.2 CPython 3.13, so
the zip carries the core and `embreex` for both (PYTHON_TARGETS below):
1. the `bsplab` wheels, built from core/ with `pip wheel ./core`: cp311 with
   this Python (or --python), and the stable-ABI cp312-abi3 wheel (any
   CPython >= 3.12) with --python313 (a command: blender_tests/python313.sh
   finds or makes one);
2. `embreex`'s manylinux wheels for CPython 3.11 and 3.13, from
   `pip download`;
3. a staging copy of addon/ with them under wheels/ and the manifest's
   `wheels = [...]` filled in (Blender installs the ones its Python takes);
4. `blender_ext.py build --split-platforms` (Blender's own extension tool,
   shipped inside the `bpy` pip package and runnable with plain Python)
   writes dist/bsplab-<version>-linux_x64.zip;
5. `blender_ext.py validate` checks the zip, with every copy of the tool
   found (one per bpy venv: .venv-bpy42, -45, -50, -52);
6. dist/bsplab_addon-<version>-legacy.zip, the same add-on as a legacy
   add-on for Blender 3.x-4.1 (no wheels: install the core separately).

With --wheels-only it stops after steps 1-2 (run_all.sh builds the wheels
in the background while the bpy venvs download; its second run finds them
up to date and makes the zips).

Run it with the project's Python 3.11 (the one that builds core/: it needs
scikit-build-core and nanobind for `--no-build-isolation`; the 3.13 build
uses build isolation when its Python lacks them). Prints the zip's path last.
"""

import argparse
import glob
import os
import pathlib
import re
import shlex
import shutil
import subprocess
import sys
import zipfile

REPO = pathlib.Path(__file__).resolve().parents[2]
# The shipped folder: all of it goes into the zips but SOURCE_EXCLUDE,
# compiled files and NOT_SHIPPED (its bpy-free tests and these tools, kept
# beside the add-on they test and build).
ADDON = REPO / "addon"
BUILD = REPO / "build" / "extension"


class PythonTarget:
    """One CPython the zip serves: which Blenders embed it, which wheel tags fit."""

    def __init__(self, version, blenders, core_tag, embreex_abi):
        self.version = version          # "3.11"
        self.blenders = blenders        # for messages
        self.core_tag = core_tag        # in the bsplab wheel's name, e.g. "-cp311-cp311-"
        self.embreex_abi = embreex_abi  # pip download --abi


PYTHON_TARGETS = (
    PythonTarget("3.11", "Blender 4.2 - 5.0", "-cp311-cp311-", "cp311"),
    # The core's wheel for 3.13 is the stable-ABI one (pyproject.toml's
    # wheel.py-api); embreex has no abi3 wheel, so its wheel is cp313.
    PythonTarget("3.13", "Blender 5.1 - 5.2", "-cp312-abi3-", "cp313"),
)
EMBREEX_PLATFORMS = ("manylinux_2_28_x86_64", "manylinux_2_17_x86_64", "manylinux2014_x86_64")
# Where blender_ext.py sits inside an installed bpy package.
BLENDER_EXT_GLOB = "bpy/*/scripts/addons_core/bl_pkg/cli/blender_ext.py"
# The bpy wheel to take blender_ext.py from when no bpy is installed anywhere.
FALLBACK_BPY = "bpy==4.2.23"
SOURCE_EXCLUDE = {"__pycache__", "wheels"}
# Top-level folders of addon/ that stay out of both zips.
NOT_SHIPPED = {"tests", "tools"}


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


def build_core_wheel(python, wheel_dir, target):
    """The bsplab wheel for TARGET, rebuilt when core/ changed since the last one.

    PYTHON is a command (a list: the Debian 13 root's Python runs through a
    wrapper) for a CPython of the target's version.
    """
    pattern = "bsplab-*{}*.whl".format(target.core_tag)
    existing = sorted(wheel_dir.glob(pattern), key=os.path.getmtime)
    if existing and existing[-1].stat().st_mtime >= newest_mtime(REPO / "core"):
        log("core wheel up to date: " + existing[-1].name)
        return existing[-1]
    for old in existing:
        old.unlink()
    check_python_version(python, target)
    cmd = python + ["-m", "pip", "wheel", REPO / "core", "--no-deps", "-w", wheel_dir]
    if can_build_without_isolation(python):
        cmd.append("--no-build-isolation")
    run(cmd)
    wheels = sorted(wheel_dir.glob(pattern))
    if len(wheels) != 1:
        sys.exit("build_extension: expected one {} wheel in {}, found {}".format(
            pattern, wheel_dir, sorted(wheel_dir.glob("bsplab-*.whl"))))
    return wheels[0]


def check_python_version(python, target):
    probe = "import sys; print('%d.%d' % sys.version_info[:2])"
    found = subprocess.run(python + ["-c", probe], capture_output=True, text=True).stdout.strip()
    if found != target.version:
        sys.exit("build_extension: {} is Python {!r}, not {} ({} embed {})".format(
            " ".join(python), found, target.version, target.blenders, target.version))


def can_build_without_isolation(python):
    probe = "import scikit_build_core, nanobind"
    return subprocess.run(python + ["-c", probe], capture_output=True).returncode == 0


def check_core_wheel(wheel, target):
    if target.core_tag not in wheel.name:
        sys.exit("build_extension: {} is not a {} wheel ({} embed CPython {})".format(
            wheel.name, target.core_tag.strip("-"), target.blenders, target.version))


def embreex_version(python):
    """The embreex version the project uses, so the bundle matches the tests."""
    probe = "import importlib.metadata as m; print(m.version('embreex'))"
    result = subprocess.run([python, "-c", probe], capture_output=True, text=True)
    return result.stdout.strip() if result.returncode == 0 else None


def download_embreex(python, wheel_dir, target):
    """embreex's wheel for TARGET's Python, downloaded by this Python's pip."""
    pattern = "embreex-*-{0}-{0}-*.whl".format(target.embreex_abi)
    version = embreex_version(python)
    existing = sorted(wheel_dir.glob(pattern))
    if existing and (version is None or "-{}-".format(version) in existing[-1].name):
        log("embreex wheel present: " + existing[-1].name)
        return existing[-1]
    for old in existing:
        old.unlink()
    spec = "embreex=={}".format(version) if version else "embreex"
    cmd = [python, "-m", "pip", "download", spec, "--no-deps", "--only-binary=:all:",
           "--python-version", target.version, "--implementation", "cp",
           "--abi", target.embreex_abi, "-d", wheel_dir]
    for platform in EMBREEX_PLATFORMS:
        cmd += ["--platform", platform]
    run(cmd)
    wheels = sorted(wheel_dir.glob(pattern))
    if not wheels:
        sys.exit("build_extension: pip download of embreex for CPython {} produced no "
                 "wheel".format(target.version))
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
         "--python-version", PYTHON_TARGETS[0].version, "-d", download])
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
    shutil.copytree(ADDON, source, ignore=lambda folder, names: [
        n for n in names if n in SOURCE_EXCLUDE or n.endswith((".pyc", ".zip"))
        or (pathlib.Path(folder) == ADDON and n in NOT_SHIPPED)])
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
    version = re.search(r'^version = "([^"]+)"', (ADDON / "blender_manifest.toml").read_text(),
                        re.MULTILINE).group(1)
    path = out_dir / "bsplab_addon-{}-legacy.zip".format(version)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        for source in sorted(ADDON.rglob("*.py")):
            relative = source.relative_to(ADDON)
            if not SOURCE_EXCLUDE.intersection(relative.parts) and relative.parts[0] not in NOT_SHIPPED:
                archive.write(source, "bsplab_addon/" + relative.as_posix())
    log("built " + str(path))
    return path


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out-dir", type=pathlib.Path, default=REPO / "dist")
    parser.add_argument("--wheel-dir", type=pathlib.Path, default=REPO / "build" / "wheels",
                        help="where the wheels are built/downloaded (reused when up to date)")
    parser.add_argument("--core-wheel", type=pathlib.Path, action="append", default=[],
                        help="use this bsplab wheel instead of building one (repeat it: one "
                             "cp311 and one cp312-abi3)")
    parser.add_argument("--python", default=sys.executable,
                        help="the Python 3.11 that runs pip (default: this one)")
    parser.add_argument("--python313", default=os.environ.get("BSPLAB_PYTHON313"),
                        help="command of a CPython 3.13 that builds the stable-ABI core wheel "
                             "(default: $BSPLAB_PYTHON313; blender_tests/python313.sh "
                             "prints one)")
    parser.add_argument("--wheels-only", action="store_true",
                        help="build/download the wheels into --wheel-dir and stop (run_all.sh "
                             "builds them while the bpy venvs download; the zip comes after)")
    args = parser.parse_args(argv)

    args.wheel_dir.mkdir(parents=True, exist_ok=True)
    # --python313 may be a command line ("blender_tests/in_debian13.sh /usr/bin/python3.13").
    builders = {"3.11": [args.python],
                "3.13": shlex.split(args.python313) if args.python313 else None}
    wheels = []
    for target in PYTHON_TARGETS:
        given = [w for w in args.core_wheel if target.core_tag in w.name]
        if given:
            core_wheel = given[-1]
        elif builders[target.version] is None:
            sys.exit("build_extension: no Python {} to build the core for {}: pass --python313 "
                     "(blender_tests/python313.sh finds or makes one)".format(
                         target.version, target.blenders))
        else:
            core_wheel = build_core_wheel(builders[target.version], args.wheel_dir, target)
        check_core_wheel(core_wheel, target)
        wheels += [core_wheel, download_embreex(args.python, args.wheel_dir, target)]
    if args.wheels_only:
        log("wheels ready: " + ", ".join(w.name for w in wheels))
        return 0
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
