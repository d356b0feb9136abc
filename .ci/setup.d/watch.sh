#!/usr/bin/env bash
# bmg160-emu watch (the live terminal view): its test drives the viewer in a real terminal,
# a detached tmux session read back with capture-pane. Idempotent: installs only if missing.
set -euo pipefail
export DEBIAN_FRONTEND=noninteractive

if command -v tmux >/dev/null 2>&1; then
    echo "watch: tmux present"
    exit 0
fi
echo "watch: installing tmux"
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
$SUDO apt-get install -y --no-install-recommends tmux \
    || { $SUDO apt-get update && $SUDO apt-get install -y --no-install-recommends tmux; }
