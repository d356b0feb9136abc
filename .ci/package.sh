#!/usr/bin/env bash
# Packaging check (issue 18): build the sdist and the wheel as a release would, check their
# metadata, install the wheel into a fresh virtual environment outside the checkout and run
# what the README advertises from it: the demo, the firmware build and capture (the wheel
# must carry the firmware sources). Run from .ci/run inside its venv; alone:
# `bash .ci/package.sh` (needs the packages of .ci/setup.d/firmware.sh).
set -euo pipefail
cd "$(dirname "$0")/.."

python3 -m pip install --quiet -e '.[package]'
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

python3 -m build --outdir "$work/dist" . >"$work/build.log" 2>&1 \
    || { tail -40 "$work/build.log"; exit 1; }
python3 -m twine check --strict "$work"/dist/*

# Both archives carry the firmware: the sdist as firmware/, the wheel as package data.
tar -tzf "$work"/dist/*.tar.gz | grep -c '/firmware/Makefile$' >/dev/null  # -c: reads to the end (no SIGPIPE)
python3 -m zipfile -l "$work"/dist/*.whl | grep -c 'bmg160_emu/firmware/sources/Makefile' >/dev/null

python3 -m venv "$work/venv"
"$work/venv/bin/python" -m pip install --quiet "$work"/dist/*.whl
cd "$work"  # nothing may come from the checkout now
export XDG_CACHE_HOME="$work/cache"  # where a shipped copy's firmware builds go
"$work/venv/bin/bmg160-emu" --version
"$work/venv/bin/bmg160-emu" demo >"$work/demo.txt"
grep -q "CHIP_ID = 0x0F" "$work/demo.txt" || { cat "$work/demo.txt"; exit 1; }
"$work/venv/bin/bmg160-emu" firmware build
"$work/venv/bin/bmg160-emu" firmware capture --duration 0.2 --output "$work/stream.txt"
[ -s "$work/stream.txt" ] || { echo "firmware capture wrote nothing"; exit 1; }
echo "package: sdist and wheel built and checked; demo, firmware build and capture ran from the wheel"
