#!/usr/bin/env bash
# The Blender demo: Build & Render through the add-on, headless, on the bpy
# 4.2 module (set up like the tests: .venv-bpy42/ and build/blender-deps/).
#
#   blender_tests/demo_in_blender.sh [PROJECT_PYTHON] [-- DEMO_ARGS...]
#
# DEMO_ARGS go to addon/tools/demo_headless.py (default: --out out/blender_demo.png).
# With a Blender binary instead:
#   BSPLAB_PYTHONPATH=build/blender-deps blender -b --factory-startup \
#       --python addon/tools/demo_headless.py -- --out out/blender_demo.png

set -u -o pipefail

# shellcheck source=blender_tests/bpy42_script.sh
. "$(dirname "${BASH_SOURCE[0]}")/bpy42_script.sh" "$@"
[ ${#SCRIPT_ARGS[@]} -gt 0 ] || SCRIPT_ARGS=(--out out/blender_demo.png)
mkdir -p out
run_script_on_bpy42 addon/tools/demo_headless.py "${SCRIPT_ARGS[@]}"
