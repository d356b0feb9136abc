#!/usr/bin/env bash
# The user-mode Linux guest engine (issues 28 and 32): Debian's linux-source-6.1 and the
# kernel's build tools, the static C library for the guest's agent (agent.c, built with
# gcc -static), then the UML kernel built once into the cache
# (~/.cache/bmg160-emu/uml-<hash>, about 4 min on 2 quiet cores; an interrupted build goes
# on where it stopped, and nothing is rebuilt while its inputs are unchanged). Exits non-zero
# when the engine is not ready afterwards.
set -euo pipefail
cd "$(dirname "$0")/../.."
export DEBIAN_FRONTEND=noninteractive

packages=(linux-source-6.1 bc flex bison libelf-dev make gcc libc6-dev patch xz-utils
          busybox-static i2c-tools kmod)
. .ci/apt-missing.sh
apt_install_missing "${packages[@]}"

PYTHONPATH=$PWD${PYTHONPATH:+:$PYTHONPATH} python3 -m bmg160_emu kernel prepare --engine uml
