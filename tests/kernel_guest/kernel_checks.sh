#!/bin/sh
# Runs INSIDE the guest (bmg160_emu.linux.guest), in the host's root file system.
# One command (on the bmg160_kernel fixture's session guest) performs every kernel check of
# tests/test_kernel_i2c_stub.py and writes the
# results to $GUEST_OUT as small text files the host-side tests assert on.
#
# Environment: PY (the host's Python, with bmg160_emu importable), GUEST_OUT, GUEST_ROOT
# (the unpacked kernel package), STUB_ARGS (chip options for `bmg160-emu stub`); KMOD and
# TOOLS (optional: the folder of the QEMU kernel's software-trigger modules, or "builtin"
# where the kernel has them (uml); this folder) add the hrtimer capture.
set -u
OUT=${GUEST_OUT:?}
: "${PY:?}"  # GUEST_ROOT: the kernel package's modules for modprobe -d, where the engine has one
STUB_ARGS=${STUB_ARGS:-}
cd /run || exit 1

step() { echo "== [$(cut -d' ' -f1 /proc/uptime)s] $*"; echo "$(cut -d' ' -f1 /proc/uptime) $*" >> "$OUT/steps.txt"; }
emu() { "$PY" -m bmg160_emu "$@"; }
# n reads of one sysfs attribute, $2 seconds apart, one value a line (the shell's own read:
# a program started per value costs a fork and an exec under UML's ptrace)
sample() { i=0; while [ $i -lt "$3" ]; do read -r v < "$IIO/$1"; echo "$v"; sleep "$2"; i=$((i + 1)); done; }

step "1. modules: i2c-stub chip_addr=0x68, i2c-dev"
modprobe ${GUEST_ROOT:+-d "$GUEST_ROOT"} i2c-stub chip_addr=0x68 || echo "modprobe i2c-stub failed"
modprobe ${GUEST_ROOT:+-d "$GUEST_ROOT"} i2c-dev || echo "modprobe i2c-dev failed"
S=$(for d in /sys/bus/i2c/devices/i2c-*; do grep -q "SMBus stub" "$d/name" && echo "${d##*/i2c-}"; done | head -n 1)
echo "$S" > "$OUT/stub_bus.txt"
# A real (non-stub) SMBus adapter for the "not an i2c-stub adapter" error: QEMU's PIIX4.
modprobe ${GUEST_ROOT:+-d "$GUEST_ROOT"} i2c-piix4 2>/dev/null
i2cdetect -l > "$OUT/i2cdetect_l.txt" 2>&1

step "1b. start bmg160-emu stub (in the background)"
# shellcheck disable=SC2086  # (not through emu(): $! must be Python's own pid)
"$PY" -m bmg160_emu stub --bus "$S" --address 0x68 $STUB_ARGS --stats "$OUT/stub_stats.json" \
    --ready-file /run/stub.ready > "$OUT/stub.log" 2>&1 &
STUB=$!
step "1c. stub command errors, while the adapter starts"
OTHER=$(i2cdetect -l | grep -v 'stub' | sed -n 's/^i2c-\([0-9]*\).*/\1/p' | head -n 1)
# one Python for the three (each start imports numpy, seconds under UML's ptrace): the
# command's own entry point, its stderr and exit status per case, as a shell would see them
"$PY" - "$OUT" "$S" ${OTHER:+"$OTHER"} <<'EOF'
import contextlib, io, sys
from bmg160_emu.cli import main
out, bus = sys.argv[1], sys.argv[2]
cases = {"err_missing.txt": ["stub", "--bus", "9"],
         "err_address.txt": ["stub", "--bus", bus, "--address", "0x69"]}
if len(sys.argv) > 3:
    cases["err_not_stub.txt"] = ["stub", "--bus", sys.argv[3]]
for name, argv in cases.items():
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(err):
        try:
            status = main(argv)
        except SystemExit as exc:
            status = exc.code
    with open(f"{out}/{name}", "w") as handle:
        handle.write(err.getvalue() + f"{status}\n")
EOF
# root without CAP_DAC_OVERRIDE on a node nobody may open: permission denied
chmod 000 /dev/i2c-$S
setpriv --bounding-set=-dac_override,-dac_read_search "$PY" -m bmg160_emu stub --bus "$S" \
    > "$OUT/err_permission.txt" 2>&1; echo $? >> "$OUT/err_permission.txt"
chmod 600 /dev/i2c-$S

i=0
while [ ! -e /run/stub.ready ] && [ $i -lt 1200 ] && kill -0 $STUB 2>/dev/null; do
    sleep 0.1; i=$((i + 1))
done
[ -e /run/stub.ready ] && echo ready > "$OUT/stub_ready.txt"
sleep 0.05  # the chip's start-up after power-on (30 ms, DS): its registers hold 0 until then

step "2. i2c-tools"
i2cget -y "$S" 0x68 0x00 > "$OUT/i2cget_chip_id.txt" 2>&1
i2cdump -y "$S" 0x68 i > "$OUT/i2cdump_i.txt" 2>&1
i2cdump -y -r 0x00-0x3f "$S" 0x68 b > "$OUT/i2cdump_b.txt" 2>&1
for n in 1 2 3 4 5 6; do i2cget -y "$S" 0x68 0x02 w; sleep 0.05; done > "$OUT/i2cget_rate_x_words.txt" 2>&1
for n in 1 2 3 4 5 6; do
    i2cdump -y -r 0x02-0x07 "$S" 0x68 i | sed -n 's/^00: //p'; sleep 0.05
done > "$OUT/i2cdump_rate_blocks.txt" 2>&1

step "3. kernel driver bmg160_i2c"
modprobe ${GUEST_ROOT:+-d "$GUEST_ROOT"} bmg160_i2c || echo "modprobe bmg160_i2c failed"
echo bmg160 0x68 > /sys/bus/i2c/devices/i2c-$S/new_device
i=0; IIO=/nowhere
while [ ! -e "$IIO/in_anglvel_x_raw" ] && [ $i -lt 100 ]; do
    sleep 0.1; i=$((i + 1)); IIO=$(ls -d /sys/bus/i2c/devices/$S-0068/iio:device* 2>/dev/null | head -n 1)
done
cat "$IIO/name" > "$OUT/iio_name.txt" 2>&1
for a in in_anglvel_scale in_anglvel_sampling_frequency in_temp_raw in_temp_offset \
         in_temp_scale in_anglvel_scale_available; do
    echo "$a $(cat "$IIO/$a" 2>&1)"
done > "$OUT/iio_attributes.txt"
i2cdump -f -y -r 0x0f-0x21 "$S" 0x68 b > "$OUT/i2cdump_after_probe.txt" 2>&1
# with the driver bound, I2C_SLAVE answers EBUSY (the adapter uses I2C_SLAVE_FORCE)
i2cget -y "$S" 0x68 0x00 > "$OUT/i2cget_busy.txt" 2>&1; echo "status $?" >> "$OUT/i2cget_busy.txt"

step "3a. default configuration: samples"
for axis in x y z; do sample "in_anglvel_${axis}_raw" 0.05 12 > "$OUT/raw_default_$axis.txt"; done
sample in_temp_raw 0.05 3 > "$OUT/temp_raw.txt"

step "3b. in_anglvel_scale 0.001065 (2000 deg/s)"
echo 0.001065 > "$IIO/in_anglvel_scale"
sleep 0.2
cat "$IIO/in_anglvel_scale" > "$OUT/scale_2000.txt"
for axis in x y z; do sample "in_anglvel_${axis}_raw" 0.05 12 > "$OUT/raw_2000_$axis.txt"; done

step "3c. in_anglvel_sampling_frequency 400"
echo 400 > "$IIO/in_anglvel_sampling_frequency"
sleep 1
cat "$IIO/in_anglvel_sampling_frequency" > "$OUT/freq_400.txt"

step "3d. idle until runtime suspend"
sleep 4
i2cget -f -y "$S" 0x68 0x11 > "$OUT/lpm1_idle.txt" 2>&1

step "3e. after resume: in_anglvel_scale 0.000133 (250 deg/s), sampling frequency 200"
for axis in x y z; do sample "in_anglvel_${axis}_raw" 0.05 12 > "$OUT/raw_resumed_2000_$axis.txt"; done
echo 0.000133 > "$IIO/in_anglvel_scale"
echo 200 > "$IIO/in_anglvel_sampling_frequency"
sleep 0.2
cat "$IIO/in_anglvel_scale" > "$OUT/scale_250.txt"
for axis in x y z; do sample "in_anglvel_${axis}_raw" 0.05 12 > "$OUT/raw_250_$axis.txt"; done
sleep 2  # a stretch of refreshes at 200 Hz for the period and jitter figures

if [ -n "${KMOD:-}" ] && { [ "$KMOD" = builtin ] || [ -e "$KMOD/iio-trig-hrtimer.ko" ]; }; then
    step "3f. buffered capture with the hrtimer trigger at 100 Hz, ODR 200 Hz"
    modprobe ${GUEST_ROOT:+-d "$GUEST_ROOT"} configfs 2>/dev/null
    mount -t configfs none /sys/kernel/config 2>/dev/null
    if [ "$KMOD" != builtin ]; then  # the QEMU kernel's (bmg160_emu.linux.guest.debian_modules)
        for m in industrialio-configfs industrialio-sw-trigger iio-trig-hrtimer; do  # dependency order
            insmod "$KMOD/$m.ko" || echo "insmod $m failed"
        done
    fi
    mkdir /sys/kernel/config/iio/triggers/hrtimer/t0
    for t in /sys/bus/iio/devices/trigger*; do
        [ "$(cat "$t/name")" = t0 ] && echo 100 > "$t/sampling_frequency"
    done
    echo monotonic > "$IIO/current_timestamp_clock"
    for e in "$IIO"/scan_elements/*_en; do echo 1 > "$e"; done
    echo t0 > "$IIO/trigger/current_trigger"
    echo 1024 > "$IIO/buffer/length"
    echo 1 > "$IIO/buffer/enable"
    "$PY" "$TOOLS/guest_iio_capture.py" 3 "/dev/${IIO##*/}" "$OUT/hrtimer_capture.bin"
    echo 0 > "$IIO/buffer/enable"
    cat "$IIO/in_anglvel_scale" > "$OUT/hrtimer_scale.txt"
fi

step "4. stop the adapter"
kill -TERM $STUB 2>/dev/null
wait $STUB
echo $? > "$OUT/stub_exit.txt"
dmesg > "$OUT/dmesg.txt"
# leave the shared guest as it was: no client, no trigger, no i2c-stub
echo 0x68 > /sys/bus/i2c/devices/i2c-$S/delete_device
rmdir /sys/kernel/config/iio/triggers/hrtimer/t0 2>/dev/null
rmmod i2c-stub
step "done"
echo done > "$OUT/done.txt"
