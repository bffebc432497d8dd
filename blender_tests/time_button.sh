#!/usr/bin/env bash
# Button-to-preview time in Blender (blender_tests/time_button.py says what it
# measures), on the bpy 4.2 module set up as the demo does it.
#
#   blender_tests/time_button.sh [PROJECT_PYTHON] [-- --scene conference --preview 50 --presses 5]

set -u -o pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO"

PY="${PYTHON:-$REPO/.venv/bin/python}"
if [ $# -gt 0 ] && [ "$1" != "--" ]; then PY="$1"; shift; fi
[ "${1:-}" = "--" ] && shift

. "$REPO/blender_tests/blender_env.sh"
check_python
ensure_bpy_venv "$REPO/.venv-bpy42" 4.2.23 || die "could not set up bpy 4.2.23"
build_extension || die "addon/build_extension.py failed"
install_deps || die "could not install the wheels into $DEPS"


PYTHONPATH="$DEPS" BLENDER_USER_RESOURCES="$(mktemp -d)" \
    "$REPO/.venv-bpy42/bin/python" blender_tests/time_button.py "$@"
