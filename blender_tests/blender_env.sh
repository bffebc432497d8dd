# Shared setup of run_all.sh, demo_in_blender.sh and time_button.sh (source it; bash).
#
# Needs REPO (the repository root) and PY (the project's Python 3.11, which
# can build core/) set. Defines:
#   ensure_bpy_venv DIR VERSION [PYTHON RUNNER]
#                                 create or reuse a venv with bpy, numpy, pytest
#   find_python313                a usable CPython 3.13; sets PY313 and RUN313
#   start_wheels, wait_wheels     the wheels build_extension needs, in the
#                                 background (stop_wheels ends them early)
#   build_extension               wheels + extension zip; sets ZIP
#   install_deps                  bsplab + embreex wheels into $DEPS (3.11)
#   install_deps313               the same into $DEPS313 (3.13, needs PY313)
# Functions return non-zero on failure.

DEPS="$REPO/build/blender-deps"
DEPS313="$REPO/build/blender-deps-313"
WHEELS="$REPO/build/wheels"
# The Debian 13 root that gives a Python 3.13 where the machine has none
# (blender_tests/in_debian13.sh); outside the clone, so that CI's fresh clones
# on one machine share it.
export BSPLAB_DEBIAN13_ROOT="${BSPLAB_DEBIAN13_ROOT:-/var/cache/bsplab/debian13}"
# What bpy 5.1+ loads at import (libGL, X11, Wayland client), and Mesa's EGL
# and software OpenGL for gpu.init() in background mode (test_gpu_draw.py).
BPY_SYSTEM_LIBS="libx11-6 libxrender1 libxxf86vm1 libxfixes3 libxi6 libxkbcommon0 libsm6 libgl1 libegl1 libwayland-client0 libegl-mesa0 libgl1-mesa-dri"

log() { printf '\n=== %s: %s\n' "$(basename "$0")" "$*"; }
die() { printf '%s: error: %s\n' "$(basename "$0")" "$*" >&2; exit 1; }

check_python() {
    { [ -x "$PY" ] || command -v "$PY" >/dev/null; } || die "no project Python at $PY"
    "$PY" -c 'import sys; assert sys.version_info[:2] == (3, 11), sys.version' \
        || die "$PY is not Python 3.11 (bpy 4.2 - 5.0 and the cp311 wheels need 3.11)"
}

ensure_bpy_venv() {  # DIR BPY_VERSION [PYTHON RUNNER]: RUNNER prefixes every command ("" on the host)
    local dir="$1" version="$2" python="${3:-$PY}" runner="${4:-}"
    # shellcheck disable=SC2086  # RUNNER is empty or one path
    if [ -e "$dir/bin/python" ] && $runner "$dir/bin/python" -c "
import importlib.metadata as m, sys, pytest
sys.exit(m.version('bpy') != '$version')" 2>/dev/null; then
        echo "reusing $dir (bpy $version)"
        return 0
    fi
    log "creating $dir with bpy==$version"
    rm -rf "$dir"
    # shellcheck disable=SC2086
    $runner "$python" -m venv "$dir" || return 1
    # The numpy that this Blender ships: < 2 for the 3.11 releases (bpy 5.0.1
    # pins it, and bpy 4.2 / 4.5 were built against numpy 1.x); bpy 5.1+
    # requires numpy >= 2.2, < 3 itself, so its own pin decides there.
    local numpy="numpy<2"
    # shellcheck disable=SC2086
    $runner "$dir/bin/python" -c 'import sys; sys.exit(sys.version_info < (3, 12))' && numpy="numpy"
    # shellcheck disable=SC2086
    $runner "$dir/bin/python" -m pip install --quiet "bpy==$version" "$numpy" pytest || return 1
}

usable_python313() {  # COMMAND: a CPython 3.13 with venv, pip and ssl
    [ -n "$1" ] && "$1" -c '
import sys, ssl, venv, ensurepip
sys.exit(sys.version_info[:2] != (3, 13))' 2>/dev/null
}

find_python313() {
    # The bpy 5.2 module and the core's 3.13 build need a CPython 3.13.
    # Preferred: one on this machine (BSPLAB_PYTHON313, pyenv's, or PATH's);
    # else Debian 13's, in a root made with debootstrap (BSPLAB_DEBIAN13=1
    # forces that route).
    RUN313=""
    if [ "${BSPLAB_DEBIAN13:-0}" != 1 ]; then
        local candidate
        for candidate in "${BSPLAB_PYTHON313:-}" \
                "${PYENV_ROOT:-$HOME/.pyenv}"/versions/3.13*/bin/python3.13 \
                "$(command -v python3.13 2>/dev/null)"; do
            if usable_python313 "$candidate"; then
                PY313="$candidate"
                echo "Python 3.13: $PY313"
                ensure_host_libs
                return
            fi
        done
    fi
    ensure_debian13_root || return 1
    RUN313="$REPO/blender_tests/in_debian13.sh"
    PY313="$DEBIAN13_PYTHON"
    echo "Python 3.13: $PY313 in the Debian 13 root $BSPLAB_DEBIAN13_ROOT"
}

apt_install() {  # PACKAGES...: Debian packages, as root or through sudo
    local sudo=""
    [ "$(id -u)" -eq 0 ] || sudo="sudo"
    $sudo env DEBIAN_FRONTEND=noninteractive apt-get update -q &&
        $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -q "$@"
}

ensure_host_libs() {  # bpy 5.1+'s system libraries on this machine, when missing
    local missing="" lib
    for lib in $BPY_SYSTEM_LIBS; do
        dpkg-query -W -f='${Status}' "$lib" 2>/dev/null | grep -q "ok installed" || missing="$missing $lib"
    done
    [ -z "$missing" ] && return 0
    log "installing bpy 5.2's system libraries:$missing"
    # shellcheck disable=SC2086
    apt_install $missing
}

# Inside the root: a venv of Debian's python3.13, which has pip (the system
# Python has none, and Debian leaves it to apt).
DEBIAN13_PYTHON=/opt/bsplab-python3.13/bin/python

ensure_debian13_root() {
    local root="$BSPLAB_DEBIAN13_ROOT"
    if [ -f "$root/.bsplab-ready" ] && [ -x "$root$DEBIAN13_PYTHON" ]; then
        echo "reusing the Debian 13 root $root"
        return 0
    fi
    if [ -f "$root/.bsplab-ready" ]; then
        make_debian13_venv
        return
    fi
    log "making a Debian 13 root with Python 3.13 in $root (debootstrap, a few minutes)"
    command -v debootstrap >/dev/null || apt_install debootstrap || return 1
    rm -rf "$root"
    mkdir -p "$(dirname "$root")"
    # The core's build (g++; cmake and ninja come from PyPI through pip's build
    # isolation) and bpy 5.2's system libraries come too.
    debootstrap --variant=minbase \
        --include=python3,python3-venv,python3-dev,ca-certificates,g++,make,libx11-6,libxrender1,libxxf86vm1,libxfixes3,libxi6,libxkbcommon0,libsm6,libgl1,libegl1,libwayland-client0,libegl-mesa0,libgl1-mesa-dri \
        trixie "$root" >"$root.debootstrap.log" 2>&1 || { tail -n 20 "$root.debootstrap.log"; return 1; }
    # Names resolve as on the host (in_debian13.sh brings the host's CA bundle).
    cp /etc/resolv.conf "$root/etc/resolv.conf" 2>/dev/null || true
    touch "$root/.bsplab-ready"
    make_debian13_venv
}

make_debian13_venv() {
    rm -rf "$BSPLAB_DEBIAN13_ROOT${DEBIAN13_PYTHON%/bin/python}"
    "$REPO/blender_tests/in_debian13.sh" /usr/bin/python3.13 -m venv "${DEBIAN13_PYTHON%/bin/python}" &&
        "$REPO/blender_tests/in_debian13.sh" "$DEBIAN13_PYTHON" -c 'import ssl, pip'
}

start_wheels() {  # needs find_python313 first: build_extension's wheels, in the background
    # The bsplab wheels (the cp312-abi3 one is a whole compile of the core for
    # the 3.13, about 3 minutes on 2 cores) and embreex's, built while the
    # bpy venvs download (network-bound); build_extension then finds them up
    # to date. In a process group of its own (setsid) so that stop_wheels can
    # end the compile with it; wait_wheels prints its output.
    WHEELS_LOG="$(mktemp)"
    log "building the wheels in the background (log shown when done)"
    setsid "$PY" "$REPO/addon/tools/build_extension.py" --wheel-dir "$WHEELS" --wheels-only \
        --python313 "${RUN313:+$RUN313 }$PY313" >"$WHEELS_LOG" 2>&1 &
    WHEELS_PID=$!
}

wait_wheels() {  # the background wheels' exit status, after their output
    [ -n "${WHEELS_PID:-}" ] || return 0
    local rc=0
    wait "$WHEELS_PID" || rc=$?
    WHEELS_PID=""
    log "the wheels (built in the background)"
    cat "$WHEELS_LOG"
    rm -f "$WHEELS_LOG"
    return "$rc"
}

stop_wheels() {  # on an early exit: end the background build, pip and the compiler with it
    [ -n "${WHEELS_PID:-}" ] || return 0
    kill -- "-$WHEELS_PID" 2>/dev/null
    wait "$WHEELS_PID" 2>/dev/null
    WHEELS_PID=""
    rm -f "$WHEELS_LOG"
}

build_extension() {  # needs find_python313 first
    log "building the wheels and the extension zip"
    ZIP="$("$PY" "$REPO/addon/tools/build_extension.py" --wheel-dir "$WHEELS" \
        --python313 "${RUN313:+$RUN313 }$PY313" | tail -n 1)" || return 1
    [ -f "$ZIP" ]
}

install_deps() {
    # A folder rather than the bpy venvs: the extension test needs a Python
    # where only the zip's wheels can provide bsplab.
    log "installing bsplab and embreex into $DEPS"
    rm -rf "$DEPS"
    "$PY" -m pip install --quiet --no-deps --target "$DEPS" \
        "$WHEELS"/bsplab-*-cp311-cp311-*.whl "$WHEELS"/embreex-*-cp311-cp311-*.whl
}

install_deps313() {  # VENV: a 3.13 venv (its pip installs; through RUN313 in the Debian 13 root)
    log "installing bsplab and embreex into $DEPS313"
    rm -rf "$DEPS313"
    # shellcheck disable=SC2086
    $RUN313 "$1/bin/python" -m pip install --quiet --no-deps --target "$DEPS313" \
        "$WHEELS"/bsplab-*-cp312-abi3-*.whl "$WHEELS"/embreex-*-cp313-cp313-*.whl
}

run_script_on_bpy42() {  # SCRIPT [ARGS...]: the demo's and time_button's set-up, then SCRIPT
    check_python
    ensure_bpy_venv "$REPO/.venv-bpy42" 4.2.23 || die "could not set up bpy 4.2.23"
    find_python313 || die "no Python 3.13 for the extension's 3.13 wheels"
    build_extension || die "addon/tools/build_extension.py failed"
    install_deps || die "could not install the wheels into $DEPS"
    local script=$1
    shift
    PYTHONPATH="$DEPS" BLENDER_USER_RESOURCES="$(mktemp -d)" \
        "$REPO/.venv-bpy42/bin/python" "$script" "$@"
}
