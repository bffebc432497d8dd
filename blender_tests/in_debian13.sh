#!/usr/bin/env bash
# Run a command inside the Debian 13 root (Python 3.13) that blender_env.sh's
# ensure_debian13_root makes where the machine has no Python 3.13 of its own.
#
#   blender_tests/in_debian13.sh COMMAND [ARGS...]
#
# The root is $BSPLAB_DEBIAN13_ROOT (default /var/cache/bsplab/debian13). The
# repository, /tmp, /proc, /sys and /dev are bound into it at the same paths,
# in a mount namespace of this command's own (unshare), so paths mean the same
# inside and out and no mount outlives the command. The working directory and
# the environment carry over. Needs root.

set -euo pipefail

ROOT="${BSPLAB_DEBIAN13_ROOT:-/var/cache/bsplab/debian13}"
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
[ -x "$ROOT/usr/bin/python3.13" ] || { echo "in_debian13.sh: no Debian 13 root at $ROOT" >&2; exit 1; }

# pip inside trusts what the host trusts (a proxy's own CA, say): the host's
# bundle replaces the root's, every time, so any variable naming
# /etc/ssl/certs/ca-certificates.crt (PIP_CERT, SSL_CERT_FILE...) means it.
cp /etc/ssl/certs/ca-certificates.crt "$ROOT/etc/ssl/certs/ca-certificates.crt"
export PIP_CERT=/etc/ssl/certs/ca-certificates.crt
export BSPLAB_IN_ROOT="$ROOT" BSPLAB_IN_REPO="$REPO" BSPLAB_IN_CWD="$PWD"
exec unshare --mount --propagation private bash -c '
set -e
for dir in /proc /sys /dev /tmp "$BSPLAB_IN_REPO"; do
    mkdir -p "$BSPLAB_IN_ROOT$dir"
    mount --rbind "$dir" "$BSPLAB_IN_ROOT$dir"
done
exec chroot "$BSPLAB_IN_ROOT" env -C "$BSPLAB_IN_CWD" "$@"' in_debian13 "$@"
