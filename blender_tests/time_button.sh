#!/usr/bin/env bash
# Button-to-preview time in Blender (blender_tests/time_button.py says what it
# measures), on the bpy 4.2 module set up as the demo does it.
#
#   blender_tests/time_button.sh [PROJECT_PYTHON] [-- --scene conference --preview 50 --presses 5]

set -u -o pipefail

# shellcheck source=blender_tests/bpy42_script.sh
. "$(dirname "${BASH_SOURCE[0]}")/bpy42_script.sh" "$@"
run_script_on_bpy42 blender_tests/time_button.py "${SCRIPT_ARGS[@]}"
