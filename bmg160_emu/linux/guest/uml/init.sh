#!/bin/sh
# SPDX-License-Identifier: GPL-2.0
# PID 1 of the uml engine's guest (bmg160_emu.linux.guest.uml): the engine contract of
# bmg160_emu.linux.guest.engine with the host's root as the guest's root (hostfs). Settings
# come from the kernel command line: guest_* words, and upper-case KEY=VAL words for the
# script.
export PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin
mount -t proc proc /proc
mount -t sysfs sys /sys
mountpoint -q /dev || mount -t devtmpfs dev /dev
mount -t tmpfs run /run
mkdir -p /run/home /run/tmp
mountpoint -q /dev/shm || mount -t tmpfs shm /dev/shm 2>/dev/null
script=; out=; modroot=; vio=; mods=; boot=; envs=
# shell built-ins where they do (every program started costs a ptrace'd fork and exec)
read -r cmdline < /proc/cmdline
for arg in $cmdline; do
    case "$arg" in
        guest_script=*) script=${arg#guest_script=} ;;
        guest_out=*) out=${arg#guest_out=} ;;
        guest_modroot=*) modroot=${arg#guest_modroot=} ;;
        guest_vio=*) vio=${arg#guest_vio=} ;;
        guest_modules=*) mods=${arg#guest_modules=} ;;
        guest_boot=*) boot=${arg#guest_boot=} ;;
        [A-Z]*=*) envs="$envs $arg" ;;
    esac
done
# the kernel's own modules: lib/modules/<release> under $modroot (modprobe -d), mounted
# over the host's /lib/modules too where the host has that folder (plain modprobe)
[ -n "$modroot" ] && [ -d /lib/modules ] \
    && mount -t hostfs -o "$modroot/lib/modules" modules /lib/modules
if [ -n "$out" ]; then
    mount -t hostfs -o "$out" results "$out" || echo "init: cannot mount the results folder $out"
fi
# A reboot (sysrq b, a panic, reboot(2)) makes UML exec itself again with the same command
# line; the engine contract wants the guest to end instead. The first boot leaves a mark
# named by this boot's token, so the second one powers off at once.
mark="$out/.uml-boot-$boot"
if [ -n "$boot" ] && [ -e "$mark" ]; then
    echo "init: the guest rebooted: powering off"
    rm -f "$mark"
    /bin/busybox poweroff -f 2>/dev/null || echo o > /proc/sysrq-trigger
fi
[ -n "$boot" ] && : > "$mark"
bus=; gpiobase=
if [ -n "$vio" ]; then
    insmod "$vio/i2c-virtio.ko" || echo "init: insmod i2c-virtio failed"
    i=0
    while [ -z "$bus" ] && [ $i -lt 200 ]; do
        for d in /sys/bus/i2c/devices/i2c-*; do
            name=; read -r name < "$d/name" 2>/dev/null
            case "$name" in *virtio*) bus=${d##*/i2c-} ;; esac
        done
        [ -z "$bus" ] && sleep 0.01; i=$((i + 1))
    done
    for c in /sys/class/gpio/gpiochip*; do
        label=; read -r label < "$c/label" 2>/dev/null
        case "$label" in virtio*) read -r gpiobase < "$c/base" ;; esac
    done
fi
for m in $(echo "$mods" | tr ',' ' '); do
    case "$m" in
        /*) insmod "$m" || echo "init: insmod $m failed" ;;
        *) modprobe -d "$modroot" "$m" || echo "init: modprobe $m failed" ;;
    esac
done
read -r release < /proc/sys/kernel/osrelease
echo "init: running $script"
cd /
env -i PATH=$PATH HOME=/run/home TMPDIR=/run/tmp BMG160_RESULTS="$out" GUEST_OUT="$out" \
    GUEST_ENGINE=uml GUEST_ROOT="$modroot" GUEST_MODULES="$modroot/lib/modules/$release" GUEST_I2C_BUS="$bus" \
    GUEST_GPIO_BASE="$gpiobase" $envs /bin/sh "$script"
status=$?
echo "init: script exited with status $status"
[ -n "$out" ] && echo $status > "$out/exit-status"
[ -n "$boot" ] && rm -f "$mark"
sync
if [ -x /bin/busybox ]; then /bin/busybox poweroff -f; fi
echo o > /proc/sysrq-trigger
