#!/usr/bin/env bash
# The instanced-scene button times (blender_tests/time_instances.py says what it
# measures), on the bpy 4.2 module set up as the demo does it.
#
#   blender_tests/time_instances.sh [PROJECT_PYTHON] [-- --side 10 --instances two_level]

set -u -o pipefail

# shellcheck source=blender_tests/bpy42_script.sh
. "$(dirname "${BASH_SOURCE[0]}")/bpy42_script.sh" "$@"
run_script_on_bpy42 blender_tests/time_instances.py "${SCRIPT_ARGS[@]}"
