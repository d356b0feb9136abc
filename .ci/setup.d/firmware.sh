#!/usr/bin/env bash
# Firmware tests (pytest marker "firmware"): Debian's AVR toolchain to build the ATmega328P
# firmware, simavr and its development files for the harness (firmware/sim/bmg160_sim.c),
# a host C compiler and make. Idempotent: installs only what is missing.
set -euo pipefail
export DEBIAN_FRONTEND=noninteractive

packages=(gcc-avr avr-libc binutils-avr simavr libsimavr-dev libelf-dev gcc make)
missing=()
for pkg in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
done
if [ "${#missing[@]}" -eq 0 ]; then
    echo "firmware: all packages present"
    exit 0
fi
echo "firmware: installing ${missing[*]}"
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
$SUDO apt-get install -y --no-install-recommends "${missing[@]}" \
    || { $SUDO apt-get update && $SUDO apt-get install -y --no-install-recommends "${missing[@]}"; }
