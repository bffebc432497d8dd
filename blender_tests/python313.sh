#!/usr/bin/env bash
# Print the command of a usable CPython 3.13 (for addon/tools/build_extension.py's
# --python313): this machine's own when it has one, else the Python of the
# Debian 13 root, made on first use (blender_env.sh's find_python313 says how).
#
#   blender_tests/python313.sh        progress on stderr, the command on stdout

set -u -o pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck source=blender_tests/blender_env.sh
. "$REPO/blender_tests/blender_env.sh"
find_python313 >&2 || die "no Python 3.13, and no Debian 13 root could be made"
echo "${RUN313:+$RUN313 }$PY313"
