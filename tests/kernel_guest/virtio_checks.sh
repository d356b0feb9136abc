#!/bin/sh
# Runs INSIDE the QEMU guest (bmg160_emu.linux.guest), chrooted in the host's root file system,
# with `bmg160-emu vhost-user-i2c` serving two chips (0x68, 0x69) on the host. One boot
# performs every check of tests/test_kernel_virtio_i2c.py and writes the results to
# $GUEST_OUT as small files the host-side tests assert on.
#
# Environment: PY (host Python with bmg160_emu and smbus2), GUEST_OUT, GUEST_ROOT (the
# unpacked kernel package), KMOD (bmg160_emu.linux.guest.kmod's bundled modules), TOOLS (this folder),
# READ_LOOP (the compiled i2c_read_loop), CAPTURE_S (seconds of buffered capture).
set -u
OUT=${GUEST_OUT:?}
: "${PY:?}" "${GUEST_ROOT:?}" "${KMOD:?}" "${TOOLS:?}" "${READ_LOOP:?}"
CAPTURE_S=${CAPTURE_S:-60}
cd /run || exit 1
step() { echo "== [$(cut -d' ' -f1 /proc/uptime)s] $*"; echo "$(cut -d' ' -f1 /proc/uptime) $*" >> "$OUT/steps.txt"; }
# A sysfs write that makes the driver talk I2C, from a process with no children. i2c-virtio
# (6.1) waits for its requests interruptibly: a signal meanwhile abandons a transfer the
# device still completes into freed memory (seen: slab corruption). Nothing here is killed.
kw() { sh -c 'echo "$1" > "$2"' kw "$1" "$2"; }
iio_of() {  # the iio:deviceN of the bmg160 at address $1 (4 hex digits)
    for d in /sys/bus/iio/devices/iio:device*; do
        case "$(readlink -f "$d")" in *-"$1"/*) basename "$d"; return ;; esac
    done
}

step "1. modules: i2c-virtio, gpio-virtio force_irq=1, i2c-dev, IIO"
if [ -z "${GUEST_I2C_BUS:-}" ]; then  # (the engine loads them when it serves virtio)
    modprobe -d "$GUEST_ROOT" i2c-dev
    insmod "$KMOD/i2c-virtio.ko" || echo "insmod i2c-virtio failed"
    insmod "$KMOD/gpio-virtio.ko" force_irq=1 || echo "insmod gpio-virtio failed"
fi
i=0; BUS=
while [ -z "$BUS" ] && [ $i -lt 50 ]; do
    for d in /sys/bus/i2c/devices/i2c-*; do
        grep -q virtio "$d/name" 2>/dev/null && BUS=${d##*/i2c-}
    done
    [ -z "$BUS" ] && sleep 0.1; i=$((i + 1))
done
echo "$BUS" > "$OUT/bus.txt"
i2cdetect -l > "$OUT/i2cdetect_l.txt" 2>&1
GPIOBASE=
for c in /sys/class/gpio/gpiochip*; do
    case "$(cat "$c/label")" in virtio*) GPIOBASE=$(cat "$c/base"); cat "$c/ngpio" > "$OUT/gpio_ngpio.txt" ;; esac
done
echo "$GPIOBASE" > "$OUT/gpio_base.txt"

step "2. i2c-tools through virtio-i2c"
i2cdetect -y "$BUS" > "$OUT/i2cdetect.txt" 2>&1
i2cget -y "$BUS" 0x68 0x00 > "$OUT/chip_id_68.txt" 2>&1
i2cget -y "$BUS" 0x69 0x00 > "$OUT/chip_id_69.txt" 2>&1
i2cget -y "$BUS" 0x50 0x00 > "$OUT/nack.txt" 2>&1; echo "status $?" >> "$OUT/nack.txt"
i2cdump -y "$BUS" 0x68 i > "$OUT/i2cdump_i.txt" 2>&1

step "3. i2c-dev program: FIFO drain and a latched status on 0x69 (INT1 = GPIO line 2)"
echo $((GPIOBASE + 2)) > /sys/class/gpio/export
# gpiolib names an exported line after the controller's line name when it has one
VALUE=/sys/class/gpio/bmg160-0x69-INT1/value
[ -e "$VALUE" ] || VALUE=/sys/class/gpio/gpio$((GPIOBASE + 2))/value
"$PY" "$TOOLS/guest_i2c_checks.py" "$BUS" 0x69 "$VALUE" > "$OUT/i2c_checks.json" 2> "$OUT/i2c_checks.err"
echo $((GPIOBASE + 2)) > /sys/class/gpio/unexport

step "4. speed: 6-byte register reads from a C program"
"$READ_LOOP" "$BUS" 0x68 0x02 6 20000 > "$OUT/speed.txt" 2>&1

step "5. kernel driver with interrupts (bmg160-board: INT1 of 0x68 on line 0, of 0x69 on line 2)"
modprobe -d "$GUEST_ROOT" bmg160_i2c || echo "modprobe bmg160_i2c failed"
insmod "$KMOD/bmg160-board.ko" bus="$BUS" gpio_base="$GPIOBASE" addr=0x68,0x69 line=0,2 \
    || echo "insmod bmg160-board failed"
i=0
while { [ -z "$(iio_of 0068)" ] || [ -z "$(iio_of 0069)" ]; } && [ $i -lt 100 ]; do sleep 0.1; i=$((i + 1)); done
D68=/sys/bus/iio/devices/$(iio_of 0068); D69=/sys/bus/iio/devices/$(iio_of 0069)
for d in "$D68" "$D69"; do
    echo "$(cat "$d/name") $(ls "$d/events" 2>/dev/null | tr '\n' ' ')"
done > "$OUT/iio_devices.txt"
cat /sys/bus/iio/devices/trigger*/name > "$OUT/triggers.txt" 2>&1
grep -i gpio /proc/interrupts > "$OUT/interrupts_before.txt"

step "6. triggered buffers with the driver's own data-ready triggers: 0x68 at 100 Hz, 0x69 at 200 Hz"
setup() {  # $1 device folder, $2 sampling frequency
    kw "$2" "$1/in_anglvel_sampling_frequency"
    echo monotonic > "$1/current_timestamp_clock"
    for e in "$1"/scan_elements/*_en; do echo 1 > "$e"; done
    name=$(cat "$1/name")
    for t in /sys/bus/iio/devices/trigger*; do
        case "$(cat "$t/name")" in "$name-dev${1##*iio:device}") cat "$t/name" > "$1/trigger/current_trigger" ;; esac
    done
    cat "$1/trigger/current_trigger" >> "$OUT/current_triggers.txt"
    echo 4096 > "$1/buffer/length"
    # the reader wakes every 32 frames, not every frame: the guest's one vCPU has the
    # interrupt handlers to run (under TCG a Python wake-up costs about a millisecond)
    echo 32 > "$1/buffer/watermark"
}
setup "$D68" 100
setup "$D69" 200
cat "$D68/in_anglvel_scale" > "$OUT/scale_68.txt"
cat "$D69/in_anglvel_scale" > "$OUT/scale_69.txt"
kw 1 "$D68/buffer/enable"; kw 1 "$D69/buffer/enable"
"$PY" "$TOOLS/guest_iio_capture.py" "$CAPTURE_S" "/dev/${D68##*/}" "$OUT/capture_100.bin" \
    "/dev/${D69##*/}" "$OUT/capture_200.bin"
kw 0 "$D68/buffer/enable"; kw 0 "$D69/buffer/enable"
grep -i gpio /proc/interrupts > "$OUT/interrupts_after.txt"

step "7. any-motion event through the driver's IIO events on 0x68 (true rate steps)"
kw "" "$D68/trigger/current_trigger" 2>/dev/null
kw 2 "$D68/events/in_anglvel_roc_either_value"
kw 1 "$D68/events/in_anglvel_roc_either_en"
"$PY" "$TOOLS/guest_iio_events.py" "/dev/${D68##*/}" 4 /run/events.ready > "$OUT/events.txt" 2>&1 &
EV=$!
i=0; while [ ! -e /run/events.ready ] && [ $i -lt 600 ]; do sleep 0.1; i=$((i + 1)); done
sleep 0.5
echo "200 0 0" > "$OUT/true_rate.txt"   # the back end watches this file
sleep 1
echo "20 -10 5" > "$OUT/true_rate.next" && mv "$OUT/true_rate.next" "$OUT/true_rate.txt"
wait $EV
kw 0 "$D68/events/in_anglvel_roc_either_en"

step "8. done"
dmesg > "$OUT/dmesg.txt"
echo done > "$OUT/done.txt"
