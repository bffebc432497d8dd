#!/usr/bin/env bash
# The Blender demo: Build & Render through the add-on, headless, on the bpy
# 4.2 module (set up like the tests: .venv-bpy42/ and build/blender-deps/).
#
#   addon_tests/in_blender/demo_in_blender.sh [PROJECT_PYTHON] [-- DEMO_ARGS...]
#
# DEMO_ARGS go to addon_tools/demo_headless.py (default: --out out/blender_demo.png).
# With a Blender binary instead:
#   BSPLAB_PYTHONPATH=build/blender-deps blender -b --factory-startup \
#       --python addon_tools/demo_headless.py -- --out out/blender_demo.png

set -u -o pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$REPO"

PY="${PYTHON:-$REPO/.venv/bin/python}"
if [ $# -gt 0 ] && [ "$1" != "--" ]; then PY="$1"; shift; fi
[ "${1:-}" = "--" ] && shift
[ $# -gt 0 ] || set -- --out out/blender_demo.png

. "$REPO/addon_tests/in_blender/blender_env.sh"
mkdir -p out
run_script_on_bpy42 addon_tools/demo_headless.py "$@"
