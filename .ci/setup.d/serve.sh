#!/usr/bin/env bash
# bmg160-emu serve: its tests build the Zephyr module's host half (zephyr/src/bmg160_emu_link.c)
# into a small C client with the host compiler. No Zephyr in CI: the Zephyr build-and-run
# test (tests/test_zephyr_build.py) skips without ZEPHYR_BASE. Idempotent.
set -euo pipefail
# shellcheck disable=SC1091
. "$(dirname "$0")/../apt-missing.sh"
apt_install_missing gcc libc6-dev
echo "serve: a C compiler for the module's host half"
