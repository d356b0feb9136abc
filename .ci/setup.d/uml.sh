#!/usr/bin/env bash
# The user-mode Linux guest engine (issue 28): Debian's linux-source-6.1 and the kernel's
# build tools, then the UML kernel built once into the cache (~/.cache/bmg160-emu/uml-<hash>,
# about 3.5 min on 2 cores; nothing is rebuilt while its inputs are unchanged).
set -euo pipefail
cd "$(dirname "$0")/../.."
export DEBIAN_FRONTEND=noninteractive

packages=(linux-source-6.1 bc flex bison libelf-dev make gcc patch xz-utils busybox-static)
. .ci/apt-missing.sh
apt_install_missing "${packages[@]}"

python3 -m bmg160_emu.linux.guest.uml_build
