# Shared setup of run_all.sh, demo_in_blender.sh and time_button.sh (source it; bash).
#
# Needs REPO (the repository root) and PY (the project's Python 3.11, which
# can build core/) set. Defines:
#   ensure_bpy_venv DIR VERSION   create or reuse a venv with bpy, numpy<2, pytest
#   build_extension               wheels + extension zip; sets ZIP
#   install_deps                  bsplab + embreex wheels into $DEPS
# Functions return non-zero on failure.

DEPS="$REPO/build/blender-deps"
WHEELS="$REPO/build/wheels"

log() { printf '\n=== %s: %s\n' "$(basename "$0")" "$*"; }
die() { printf '%s: error: %s\n' "$(basename "$0")" "$*" >&2; exit 1; }

check_python() {
    { [ -x "$PY" ] || command -v "$PY" >/dev/null; } || die "no project Python at $PY"
    "$PY" -c 'import sys; assert sys.version_info[:2] == (3, 11), sys.version' \
        || die "$PY is not Python 3.11 (bpy 4.2/5.0 and the bundled wheels need 3.11)"
}

ensure_bpy_venv() {  # DIR BPY_VERSION
    local dir="$1" version="$2"
    if [ -x "$dir/bin/python" ] && "$dir/bin/python" -c "
import importlib.metadata as m, sys, pytest
sys.exit(m.version('bpy') != '$version')" 2>/dev/null; then
        echo "reusing $dir (bpy $version)"
        return 0
    fi
    log "creating $dir with bpy==$version"
    rm -rf "$dir"
    "$PY" -m venv "$dir" || return 1
    # numpy < 2: bpy 5.0.1 pins it, and bpy 4.2 was built against numpy 1.x.
    "$dir/bin/python" -m pip install --quiet "bpy==$version" "numpy<2" pytest || return 1
}

build_extension() {
    log "building the wheels and the extension zip"
    ZIP="$("$PY" "$REPO/addon/build_extension.py" --wheel-dir "$WHEELS" | tail -n 1)" || return 1
    [ -f "$ZIP" ]
}

install_deps() {
    # A folder rather than the bpy venvs: the extension test needs a Python
    # where only the zip's wheels can provide bsplab.
    log "installing bsplab and embreex into $DEPS"
    rm -rf "$DEPS"
    "$PY" -m pip install --quiet --no-deps --target "$DEPS" \
        "$WHEELS"/bsplab-*.whl "$WHEELS"/embreex-*.whl
}

run_script_on_bpy42() {  # SCRIPT [ARGS...]: the demo's and time_button's set-up, then SCRIPT
    check_python
    ensure_bpy_venv "$REPO/.venv-bpy42" 4.2.23 || die "could not set up bpy 4.2.23"
    build_extension || die "addon/build_extension.py failed"
    install_deps || die "could not install the wheels into $DEPS"
    local script=$1
    shift
    PYTHONPATH="$DEPS" BLENDER_USER_RESOURCES="$(mktemp -d)" \
        "$REPO/.venv-bpy42/bin/python" "$script" "$@"
}
