#!/usr/bin/env bash
# Installs Debian's qemu-user when qemu-x86_64 is missing (`make test-core`):
# core/tests/library/test_isa_levels.py runs the module on an emulated CPU with only
# SSE2 (QEMU's qemu64 model) to prove the wheel runs on any x86-64.
set -euo pipefail
command -v qemu-x86_64 >/dev/null && exit 0
echo "test-core: installing Debian's qemu-user (the SSE2-only CPU test)"
sudo_cmd=""
[ "$(id -u)" -eq 0 ] || sudo_cmd="sudo"
$sudo_cmd env DEBIAN_FRONTEND=noninteractive apt-get update -qq
$sudo_cmd env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq qemu-user >/dev/null
