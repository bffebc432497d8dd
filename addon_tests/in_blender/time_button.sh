#!/usr/bin/env bash
# Button-to-preview time in Blender (addon_tests/in_blender/time_button.py says what it
# measures), on the bpy 4.2 module set up as the demo does it.
#
#   addon_tests/in_blender/time_button.sh [PROJECT_PYTHON] [-- --scene conference --preview 50 --presses 5]

set -u -o pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$REPO"

PY="${PYTHON:-$REPO/.venv/bin/python}"
if [ $# -gt 0 ] && [ "$1" != "--" ]; then PY="$1"; shift; fi
[ "${1:-}" = "--" ] && shift

. "$REPO/addon_tests/in_blender/blender_env.sh"
run_script_on_bpy42 addon_tests/in_blender/time_button.py "$@"
