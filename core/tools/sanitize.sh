#!/usr/bin/env bash
# Sanitizer builds of the core, beside (never instead of) the normal install.
#
#   core/tools/sanitize.sh asan [PYTEST ARGS...]
#       AddressSanitizer + UndefinedBehaviorSanitizer (with float-cast-overflow,
#       which GCC leaves out of "undefined"): builds the core with
#       BSPLAB_SANITIZE=address,undefined,float-cast-overflow in
#       core/build/asan, installs it into out/sanitize/asan/site and runs the
#       core suite's fast part (pytest -m "not slow") against it; extra
#       arguments go to pytest. Fails on any failing test and on any ASan or
#       UBSan report. `make test` runs this (make test-sanitize).
#   core/tools/sanitize.sh tsan [ARGS...]
#       ThreadSanitizer: builds with BSPLAB_SANITIZE=thread in core/build/tsan,
#       installs into out/sanitize/tsan/site and runs core/tools/tsan_check.py
#       (every method built with threads=2 on a few scenes, parallel traces),
#       keeping the reports whose stacks reach core/src. Run by hand, not in CI.
#
# BSPLAB_PYTHON (default .venv/bin/python) must have numpy, pytest, embreex,
# scikit-build-core and nanobind (make venv). The compiler is GCC (CXX,
# default g++): the runtimes preloaded below are the ones it ships.
# docs/testing.md says why the options are what they are.
set -euo pipefail
cd "$(dirname "$0")/../.."
ROOT=$PWD

kind=${1:-}
[ $# -gt 0 ] && shift
case "$kind" in
  asan) sanitizers=address,undefined,float-cast-overflow; runtimes="libasan.so libubsan.so" ;;
  tsan) sanitizers=thread; runtimes="libtsan.so" ;;
  *) echo "usage: $0 asan|tsan [ARGS...]" >&2; exit 2 ;;
esac

PYTHON=${BSPLAB_PYTHON:-$ROOT/.venv/bin/python}
export CXX=${CXX:-g++}
OUT=$ROOT/out/sanitize/$kind
SITE=$OUT/site
LOGS=$OUT/logs

if ! "$CXX" -v 2>&1 | grep -q "^gcc version"; then
  echo "sanitize: $CXX is not GCC; the runtimes preloaded here are GCC's (CXX=g++)" >&2
  exit 2
fi
# The runtimes come with GCC on Debian (libgcc-N-dev depends on libasan,
# libubsan and libtsan); install them if a slimmer compiler setup lacks them.
runtime_path() { "$CXX" -print-file-name="$1"; }
missing_runtimes() {
  local r
  for r in $runtimes libstdc++.so; do
    case "$(runtime_path "$r")" in /*) ;; *) echo "$r" ;; esac
  done
}
if [ -n "$(missing_runtimes)" ]; then
  pkg="libgcc-$("$CXX" -dumpversion | cut -d. -f1)-dev"
  echo "sanitize: $CXX lacks $(missing_runtimes | xargs); installing $pkg" >&2
  if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null; then
    echo "sanitize: installing $pkg needs root and apt-get" >&2
    exit 1
  fi
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$pkg"
  if [ -n "$(missing_runtimes)" ]; then
    echo "sanitize: still missing after installing $pkg: $(missing_runtimes | xargs)" >&2
    exit 1
  fi
fi
# The sanitizer runtime must come first in the process (Python is not built
# with it); libstdc++ is loaded with it so that ASan's __cxa_throw interceptor
# finds the real one (the core throws C++ exceptions that become Python ones).
preload=""
for r in $runtimes libstdc++.so.6; do preload="$preload $(runtime_path "$r")"; done
preload=${preload# }

# Build + install into a folder of its own. CMake's build folder
# (core/build/$kind) keeps it incremental.
start=$SECONDS
echo "sanitize: building the core with -fsanitize=$sanitizers (core/build/$kind)"
rm -rf "$SITE"
"$PYTHON" -m pip install -q --no-build-isolation --no-deps --target "$SITE" \
  -C cmake.define.BSPLAB_SANITIZE="$sanitizers" -C build-dir="build/$kind" \
  -C install.strip=false ./core
core_so=$(ls "$SITE"/bsplab/_core*.so)
flavour=${runtimes%%.so*}  # libasan / libtsan
if ! readelf -d "$core_so" | grep -q "NEEDED.*${flavour}"; then
  echo "sanitize: $core_so is not linked against $flavour" >&2
  exit 1
fi
echo "sanitize: built in $((SECONDS - start)) s: $core_so"

rm -rf "$LOGS"
mkdir -p "$LOGS"
export PYTHONPATH=$SITE${PYTHONPATH:+:$PYTHONPATH}
# conftest.py stops the run unless bsplab._core comes from here.
export BSPLAB_EXPECT_CORE=$SITE/bsplab

status=0
if [ "$kind" = asan ]; then
  # detect_leaks=0: CPython and numpy keep interned objects and module state
  # alive until exit by design, so LeakSanitizer would report thousands of
  # "leaks" outside the core; the core owns its memory through std::vector
  # and unique_ptr. malloc_context_size=5 (30 by default) keeps 5 frames of
  # allocation stacks and halves the run time. abort_on_error=1: the first
  # report aborts, and pytest's faulthandler prints the Python stack (which
  # test) on stderr. ASan's reports go to $LOGS, one file per process, so
  # a report from a subprocess (whose exit status a test may expect to be
  # non-zero) fails the run too.
  export ASAN_OPTIONS="detect_leaks=0:malloc_context_size=5:halt_on_error=1:abort_on_error=1:check_initialization_order=1:strict_init_order=1:log_path=$LOGS/asan"
  export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:abort_on_error=1"
  # --capture=sys: pytest captures Python's output but leaves file
  # descriptor 2 alone, so UBSan's report (which ignores log_path in GCC's
  # combined runtimes) reaches the log even when it aborts the process.
  # addon/tests is its own rootdir (the Makefile's test-core says why).
  LD_PRELOAD="$preload" "$PYTHON" -m pytest -q -p no:cacheprovider --capture=sys \
    -m "not slow" core/tests "$@" || status=$?
  LD_PRELOAD="$preload" "$PYTHON" -m pytest -q -p no:cacheprovider --capture=sys \
    -m "not slow" --rootdir addon/tests addon/tests "$@" || status=$?
else
  # report_signal_unsafe=0: CPython's signal handlers are not the core's.
  # exitcode=0: the filter below decides what counts.
  export TSAN_OPTIONS="halt_on_error=0:exitcode=0:report_signal_unsafe=0:history_size=4:second_deadlock_stack=1:log_path=$LOGS/tsan"
  LD_PRELOAD="$preload" "$PYTHON" core/tools/tsan_check.py "$@" || status=$?
fi

if [ "$kind" = asan ]; then
  reports=$(find "$LOGS" -type f | sort)
  if [ -n "$reports" ]; then
    echo "sanitize: AddressSanitizer reports:" >&2
    for f in $reports; do echo "==== $f" >&2; cat "$f" >&2; done
    [ "$status" != 0 ] || status=1
  fi
else
  # Keeps the reports with a frame in core/src; the full logs stay in $LOGS.
  unset PYTHONPATH BSPLAB_EXPECT_CORE
  "$PYTHON" core/tools/tsan_check.py --filter "$LOGS" || status=1
fi
echo "sanitize: $kind finished in $((SECONDS - start)) s, status $status"
exit $status
