#!/usr/bin/env bash
# Run the add-on's test suite on every tested Blender:
#   1. bpy 4.2.23 LTS (pip module, Python 3.11, in-process pytest): the manifest's minimum
#   2. bpy 4.5.15 LTS (Python 3.11)
#   3. bpy 5.0.1      (Python 3.11)
#   4. bpy 5.2.3 LTS  (Python 3.13: this machine's own 3.13, else the Debian 13
#      root's, blender_env.sh's find_python313)
#   5. Debian's Blender 3.4.1 binary (pytest inside Blender; the legacy add-on)
#   6. Debian 13's Blender 4.3.2 binary in the Debian 13 root (pytest inside
#      Blender, the extension installed from the zip; Python 3.13)
#
#   blender_tests/run_all.sh [PROJECT_PYTHON]
#
# PROJECT_PYTHON (default: $PYTHON, else .venv/bin/python) is a Python 3.11
# that can build core/ (scikit-build-core, nanobind). The script
# - creates or reuses .venv-bpy42/, -45/, -50/ and -52/ (git-ignored) with
#   bpy, the numpy that release ships (< 2 for 3.11, bpy 5.2's own pin) and
#   pytest;
# - builds the bsplab wheels (cp311, and cp312-abi3 with the Python 3.13: a
#   whole compile of the core) in the background while the venvs download,
#   then the extension zip (addon/tools/build_extension.py, which also
#   validates the zip with each bpy's copy of Blender's own tool);
# - installs the bsplab and embreex wheels into build/blender-deps/ (3.11)
#   and build/blender-deps-313/, put on the path of each run (PYTHONPATH, or
#   BSPLAB_PYTHONPATH inside Blender), so the extension test can check that
#   the zip alone brings the core;
# - apt-installs Debian's blender, python3-numpy and python3-pytest unless
#   they are already there;
# - runs the four GUI checks (gui_check*.py: the modal Build & Render with a
#   real Esc, A/B, the ray inspector, the overlay) in a real window under
#   Xvfb on both Debian Blenders (3.4 and 4.3); BSPLAB_GUI_CHECK=0 skips them.
# Exits non-zero if any run fails.

set -u -o pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO"

PY="${1:-${PYTHON:-$REPO/.venv/bin/python}}"
# shellcheck source=blender_tests/blender_env.sh
. "$REPO/blender_tests/blender_env.sh"
check_python

declare -a TIMES=()
SECONDS=0
lap() {  # NAME: the time since the last lap
    TIMES+=("$(printf '%-44s %4d s' "$1" "$SECONDS")")
    SECONDS=0
}

LOGS="$(mktemp -d)"
trap 'stop_wheels; rm -rf "$LOGS"' EXIT

find_python313 || die "no Python 3.13 for bpy 5.2"
# The wheels compile (CPU) while the venvs download (network): about 2
# minutes less than one after the other in a fresh clone.
start_wheels
ensure_bpy_venv "$REPO/.venv-bpy42" 4.2.23 || die "could not set up bpy 4.2.23"
ensure_bpy_venv "$REPO/.venv-bpy45" 4.5.15 || die "could not set up bpy 4.5.15"
ensure_bpy_venv "$REPO/.venv-bpy50" 5.0.1 || die "could not set up bpy 5.0.1"
ensure_bpy_venv "$REPO/.venv-bpy52" 5.2.3 "$PY313" "$RUN313" || die "could not set up bpy 5.2.3"
lap "set-up: bpy venvs (reused when present), wheels started"
wait_wheels || die "building the wheels failed (addon/tools/build_extension.py --wheels-only)"
lap "set-up: the rest of the wheels' build"
build_extension || die "addon/tools/build_extension.py failed"
install_deps || die "could not install the wheels into $DEPS"
install_deps313 "$REPO/.venv-bpy52" || die "could not install the wheels into $DEPS313"
lap "set-up: zip, validation"

export BSPLAB_STRICT=1 BSPLAB_EXTENSION_ZIP="$ZIP"
declare -a RESULTS=()
STATUS=0

record() {  # NAME RC
    if [ "$2" -eq 0 ]; then RESULTS+=("$1: passed"); else RESULTS+=("$1: FAILED (exit $2)"); STATUS=1; fi
}

count() {  # WORD: the sum of "N WORD" over pytest's closing lines
    grep -hE '^=+ .* in [0-9.]+s' "$LOGS"/*.log 2>/dev/null \
        | grep -oE "[0-9]+ $1" | awk '{ s += $1 } END { print s + 0 }'
}

# --- bpy module runs ---------------------------------------------------------

run_bpy_suite() {  # VENV DEPS [RUNNER]
    local venv="$1" deps="$2" runner="${3:-}" name
    # shellcheck disable=SC2086  # RUNNER is empty or one path
    name="$($runner "$REPO/$venv/bin/python" -c 'import importlib.metadata as m, sys
print("bpy %s (Python %d.%d)" % ((m.version("bpy"),) + sys.version_info[:2]))')"
    log "pytest on $venv: $name"
    USER_DIR="$(mktemp -d)"
    # shellcheck disable=SC2086
    PYTHONPATH="$deps" BLENDER_USER_RESOURCES="$USER_DIR" \
        $runner "$REPO/$venv/bin/python" -m pytest blender_tests -p no:cacheprovider -ra 2>&1 \
        | tee "$LOGS/${venv#.}.log"
    record "$name" "${PIPESTATUS[0]}"
    rm -rf "$USER_DIR"
    lap "suite: $name"
}

run_bpy_suite .venv-bpy42 "$DEPS"
run_bpy_suite .venv-bpy45 "$DEPS"
run_bpy_suite .venv-bpy50 "$DEPS"
run_bpy_suite .venv-bpy52 "$DEPS313" "$RUN313"

# --- Debian's Blender binary ---------------------------------------------------

export DEBIAN_FRONTEND=noninteractive

if command -v blender >/dev/null && /usr/bin/python3 -c 'import numpy, pytest' 2>/dev/null; then
    echo "blender, python3-numpy and python3-pytest already installed"
else
    log "installing Debian's blender"
    apt_install blender python3-numpy python3-pytest || die "apt-get install blender failed"
fi

BLENDER_VERSION="$(blender --version 2>/dev/null | head -n 1)"
log "pytest inside $BLENDER_VERSION"
USER_DIR="$(mktemp -d)"
BSPLAB_PYTHONPATH="$DEPS" BLENDER_USER_RESOURCES="$USER_DIR" \
    blender --background --factory-startup -noaudio --python-exit-code 1 \
    --python blender_tests/run_in_blender.py 2>&1 | tee "$LOGS/blender.log"
record "$BLENDER_VERSION" "${PIPESTATUS[0]}"
rm -rf "$USER_DIR"
lap "suite: $BLENDER_VERSION (with its apt install)"

# --- the GUI checks in a real window (Xvfb) ----------------------------------

# Each check in its own Blender under Xvfb: the modal Build & Render (cancel
# and K sweep), A/B, the ray inspector, the overlay. BSPLAB_GUI_CHECK=0 skips
# them (a developer's quicker run); CI runs them.
GUI_CHECKS="gui_check gui_check_compare gui_check_inspector gui_check_overlay"

run_gui_checks() {  # NAME DEPS OUT [RUNNER]: the four checks on RUNNER's blender
    # (BSPLAB_GUI_EXTENSION_ZIP: with the zip installed, bsplab_test_utils.start_gui_check)
    local name="$1" deps="$2" out="$3" runner="${4:-}" check rc
    rm -rf "$out"
    for check in $GUI_CHECKS; do
        log "$check on $name (Xvfb)"
        # shellcheck disable=SC2086  # RUNNER is empty or one path
        BSPLAB_PYTHONPATH="$deps" BLENDER_USER_RESOURCES="$(mktemp -d)" \
            $runner xvfb-run -a -s "-screen 0 1600x900x24" blender --factory-startup -noaudio \
            --python "blender_tests/$check.py" -- "$out" > "$LOGS/$check.txt" 2>&1
        rc=$?
        cat "$out/$check.json" 2>/dev/null || tail -n 30 "$LOGS/$check.txt"
        record "$check ($name, Xvfb)" "$rc"
    done
    lap "GUI checks: $name"
}

GUI_PACKAGES="xvfb xdotool imagemagick"
if [ "${BSPLAB_GUI_CHECK:-1}" != 0 ]; then
    if ! command -v xvfb-run >/dev/null || ! command -v xdotool >/dev/null \
            || ! command -v import >/dev/null; then
        log "installing $GUI_PACKAGES"
        # shellcheck disable=SC2086
        apt_install $GUI_PACKAGES || die "apt-get install $GUI_PACKAGES failed"
    fi
    run_gui_checks "$BLENDER_VERSION" "$DEPS" "$REPO/build/gui_check"
fi

# --- Debian 13's Blender 4.3 binary (the extension path, in the Debian 13 root) --

# Debian 13's own blender runs on the system Python 3.13: the core is the
# cp312-abi3 wheel (build/blender-deps-313). In the root that
# ensure_debian13_root makes (reused once there, as are its packages).
ensure_debian13_root || die "could not make the Debian 13 root"
IN13="$REPO/blender_tests/in_debian13.sh"
if ! "$IN13" sh -c 'command -v blender && command -v xvfb-run && command -v xdotool && command -v import &&
        /usr/bin/python3 -c "import numpy, pytest"' >/dev/null 2>&1; then
    log "installing blender in the Debian 13 root"
    # shellcheck disable=SC2086
    "$IN13" env DEBIAN_FRONTEND=noninteractive sh -c "apt-get update -q &&
        apt-get install -y -q blender python3-numpy python3-pytest $GUI_PACKAGES" \
        || die "apt-get install blender in the Debian 13 root failed"
fi
lap "set-up: Debian 13's blender (installed when missing)"
BLENDER13_VERSION="$("$IN13" blender --version 2>/dev/null | head -n 1) (Debian 13)"
log "pytest inside $BLENDER13_VERSION"
USER_DIR="$(mktemp -d)"
BSPLAB_PYTHONPATH="$DEPS313" BLENDER_USER_RESOURCES="$USER_DIR" \
    "$IN13" blender --background --factory-startup -noaudio --python-exit-code 1 \
    --python blender_tests/run_in_blender.py 2>&1 | tee "$LOGS/blender13.log"
record "$BLENDER13_VERSION" "${PIPESTATUS[0]}"
rm -rf "$USER_DIR"
lap "suite: $BLENDER13_VERSION"
if [ "${BSPLAB_GUI_CHECK:-1}" != 0 ]; then
    # Through the extension path: each check installs the zip in its empty
    # user folder and runs the installed add-on, its core from the zip's
    # wheels (no BSPLAB_PYTHONPATH).
    BSPLAB_GUI_EXTENSION_ZIP="$ZIP" \
        run_gui_checks "$BLENDER13_VERSION, the extension" "" "$REPO/build/gui_check_debian13" "$IN13"
fi

log "summary"
printf '  %s\n' "${RESULTS[@]}"
echo "time of each part:"
printf '  %s\n' "${TIMES[@]}"
# One closing line over the six runs (a failed run may have no counts:
# STATUS is what decides).
FAILED=$(( $(count failed) + $(count error) ))
[ "$STATUS" -eq 0 ] || [ "$FAILED" -gt 0 ] || FAILED=1
echo "blender_tests: $(count passed) passed, $FAILED failed, $(count skipped) skipped"
exit "$STATUS"
