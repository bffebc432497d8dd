# The shared prelude of the scripts that run one Python script on the bpy
# 4.2 module, set up as the tests set it up (demo_in_blender.sh,
# time_button.sh). Sourced with the caller's arguments:
#
#   . "$(dirname "${BASH_SOURCE[0]}")/bpy42_script.sh" "$@"
#
# It goes to the repository's root (REPO), takes PY from the first argument
# unless that is "--" (else $PYTHON, else .venv/bin/python), drops the "--",
# leaves the rest in the array SCRIPT_ARGS (for the script) and loads
# blender_env.sh (run_script_on_bpy42 and the set-up it calls).
# shellcheck shell=bash

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO" || return 1

PY="${PYTHON:-$REPO/.venv/bin/python}"
if [ $# -gt 0 ] && [ "$1" != "--" ]; then PY="$1"; shift; fi
[ "${1:-}" = "--" ] && shift
SCRIPT_ARGS=("$@")

# shellcheck source=blender_tests/blender_env.sh
. "$REPO/blender_tests/blender_env.sh"
