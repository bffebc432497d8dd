#!/usr/bin/env bash
# Builds and runs the C++ unit tests (GoogleTest) - `make test-cpp`.
#
#   core/cpp_tests/run.sh [GTEST ARGS...]     e.g. --gtest_filter='Cell*'
#
# A CMake project of its own in core/build/cpp-tests (incremental): the core's
# library bsplab_core, built in Debug (-O1 -g, asserts on, no Python), and
# the executable bsplab_cpp_tests linking it. Installs Debian's libgtest-dev
# with apt-get when its headers are missing (as blender_tests/run_all.sh does
# with Blender). docs/testing.md.
set -euo pipefail
cd "$(dirname "$0")/../.."
BUILD=core/build/cpp-tests

if [ ! -f /usr/include/gtest/gtest.h ]; then
  echo "cpp-tests: installing Debian's libgtest-dev"
  sudo_cmd=""
  [ "$(id -u)" -eq 0 ] || sudo_cmd="sudo"
  $sudo_cmd env DEBIAN_FRONTEND=noninteractive apt-get update -qq
  $sudo_cmd env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libgtest-dev >/dev/null
fi

generator=()
command -v ninja >/dev/null && [ ! -f "$BUILD/Makefile" ] && generator=(-G Ninja)
cmake -S core -B "$BUILD" "${generator[@]}" -DCMAKE_BUILD_TYPE=Debug \
  -DBSPLAB_PYTHON_MODULE=OFF -DBSPLAB_CPP_TESTS=ON >/dev/null
cmake --build "$BUILD" --parallel "$(nproc)"
"$BUILD/cpp_tests/bsplab_cpp_tests" --gtest_brief=1 "$@"
