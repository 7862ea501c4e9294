#!/bin/bash
# tools/vcan_guest.sh -- the project's SocketCAN test guest (the recipe of ../shared/vcan/vcan-guest.sh):
# what only a kernel CAN stack has (the broadcast manager's SYNC and heartbeat, error frames, candump)
# is tested in it by tests/master/test_socketcan.py, skipped with the reason where the guest cannot boot.
# Under software emulation (TCG) it tests function, not timing.
#
# vcan_guest.sh -- boot a throwaway Linux guest under qemu whose kernel has SocketCAN
# (vcan, can-raw, can-bcm, can-gw) and run one command in it, with the HOST's own
# userland (shared read-only over virtio-9p, writes go to a tmpfs overlay).
#
#   vcan_guest.sh setup                 # once: packages, Debian kernel, initramfs (under $VCAN_WORK)
#   vcan_guest.sh run 'shell command'   # boot, make vcan0 up, run the command, power off
#   vcan_guest.sh run-file script.sh    # same, the command being a script file on the host
#
# The command runs as root in the guest, in the directory it was started from on the host
# ($PWD, as seen through the read-only share + overlay), with the host's PATH (pyenv
# shims included).  Its stdout+stderr go to the console and to $VCAN_OUT/output.log,
# its exit status to $VCAN_OUT/rc; the script exits with it.  $VCAN_OUT is writable from
# the guest at the same path (only that folder persists; everything else the guest
# writes is lost at power-off).  The host's environment variables are NOT passed in:
# set what the command needs inside it ('FOO=1 python x.py').  The host's /tmp is seen
# as it is (no tmpfs over it), so venvs and checkouts kept there work in the guest.
#
# Environment (defaults):
#   VCAN_WORK=/tmp/vcan      kernel, initramfs, downloads
#   VCAN_OUT=$VCAN_WORK/out  shared read-write folder (emptied of output.log/rc each run)
#   VCAN_ACCEL=tcg           tcg | kvm  (see README.txt: kvm does NOT work on a PVM host)
#   VCAN_MEM=2048 VCAN_SMP=2 guest memory (MiB) and vCPUs
#   VCAN_IFACES=vcan0        vcan interfaces created and set up before the command
#   VCAN_TIMEOUT=3600        seconds before qemu is killed
#   VCAN_APPEND=             extra kernel command-line arguments
#
# Needs: root, Debian apt (setup only), python3 (setup: unpacks vmlinux), ~500 MB under
# $VCAN_WORK (the unpacked kernel package, its modules, an uncompressed vmlinux).  No network in
# the guest.  Nothing here names a package mirror: apt uses the machine's own configuration.
set -euo pipefail

WORK=${VCAN_WORK:-/tmp/vcan}
OUT=${VCAN_OUT:-$WORK/out}
ACCEL=${VCAN_ACCEL:-tcg}
MEM=${VCAN_MEM:-2048}
SMP=${VCAN_SMP:-2}
IFACES=${VCAN_IFACES:-vcan0}
TIMEOUT=${VCAN_TIMEOUT:-3600}
APPEND_EXTRA=${VCAN_APPEND:-}

# modules the initramfs loads before it can see the host's root (the rest come from
# the kernel's full module tree, bind-mounted into the guest's /lib/modules)
EARLY_MODS="virtio_pci 9pnet_virtio 9p overlay"

die() { echo "vcan-guest: $*" >&2; exit 1; }

kver() {
    local k
    k=$(ls "$WORK"/kernel/boot/vmlinuz-* 2>/dev/null | head -1) || true
    [ -n "$k" ] || die "no kernel under $WORK/kernel: run '$0 setup' first"
    basename "$k" | sed 's/^vmlinuz-//'
}

cmd_setup() {
    [ "$(id -u)" = 0 ] || die "setup needs root (apt-get)"
    mkdir -p "$WORK/dl" "$OUT"
    local need=()
    command -v qemu-system-x86_64 >/dev/null || need+=(qemu-system-x86)
    dpkg -s busybox-static >/dev/null 2>&1 || need+=(busybox-static)   # the initramfs needs the static one
    command -v depmod >/dev/null || need+=(kmod)
    command -v cpio >/dev/null || need+=(cpio)
    command -v ip >/dev/null || need+=(iproute2)
    command -v cansend >/dev/null || need+=(can-utils)
    if [ ${#need[@]} -gt 0 ]; then
        apt-get update
        DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends "${need[@]}"
    fi
    # the kernel package that the linux-image-amd64 metapackage points at, unpacked
    # under $WORK (the host's /boot and /lib/modules are not touched)
    local pkg
    pkg=$(apt-cache depends linux-image-amd64 2>/dev/null | awk '/Depends: linux-image-[0-9]/{print $2; exit}')
    if [ -z "$pkg" ]; then apt-get update; pkg=$(apt-cache depends linux-image-amd64 | awk '/Depends: linux-image-[0-9]/{print $2; exit}'); fi
    [ -n "$pkg" ] || die "cannot resolve linux-image-amd64"
    local KVER=${pkg#linux-image-}
    if [ ! -f "$WORK/kernel/boot/vmlinuz-$KVER" ]; then
        rm -rf "$WORK/kernel"
        ( cd "$WORK/dl" && rm -f "$pkg"_*.deb && apt-get download "$pkg" )
        dpkg-deb -x "$WORK"/dl/"$pkg"_*.deb "$WORK/kernel"
        depmod -b "$WORK/kernel" "$KVER"
    fi
    # the uncompressed ELF vmlinux boots by PVH (no xz decompression in the emulated CPU: ~4 s
    # faster under TCG); the bzImage stays the fallback
    [ -f "$WORK/kernel/boot/vmlinux-$KVER" ] || extract_vmlinux "$WORK/kernel/boot/vmlinuz-$KVER" \
        "$WORK/kernel/boot/vmlinux-$KVER" || echo "vcan-guest: no vmlinux extracted; the bzImage will boot"
    grep -q '^CONFIG_CAN_VCAN=[my]' "$WORK/kernel/boot/config-$KVER" || die "kernel $KVER has no vcan"
    build_initramfs "$KVER"
    echo "vcan-guest: ready: kernel $KVER, initramfs $WORK/initramfs.cpio.gz"
}

extract_vmlinux() {
    python3 - "$1" "$2" <<'PY'
import lzma, sys
d = open(sys.argv[1], "rb").read()
i = d.find(b"\xfd7zXZ\x00")
if i < 0:
    sys.exit("not an xz-compressed bzImage")
out = lzma.LZMADecompressor(format=lzma.FORMAT_XZ).decompress(d[i:])
if out[:4] != b"\x7fELF":
    sys.exit("no ELF inside")
open(sys.argv[2], "wb").write(out)
PY
}

build_initramfs() {
    local KVER=$1 root="$WORK/initramfs.d" m f
    rm -rf "$root"; mkdir -p "$root"/{bin,mods,proc,sys,dev,lower,rw,newroot}
    cp /bin/busybox "$root/bin/busybox"
    : > "$root/modlist"
    for m in $EARLY_MODS; do
        modprobe -d "$WORK/kernel" -S "$KVER" --show-depends "$m" | awk '$1=="insmod"{print $2}' |
        while read -r f; do
            b=$(basename "$f")
            grep -qx "$b" "$root/modlist" || { cp "$f" "$root/mods/"; echo "$b" >> "$root/modlist"; }
        done
    done
    cat > "$root/init" <<'EOF'
#!/bin/busybox sh
/bin/busybox --install -s /bin
export PATH=/bin
mount -t proc proc /proc; mount -t sysfs sys /sys; mount -t devtmpfs dev /dev
for m in $(cat /modlist); do insmod /mods/$m || echo "init: insmod $m failed"; done
fail() { echo "init: $*"; poweroff -f; }
# vcan_* variables come from the kernel command line
mount -t 9p -o trans=virtio,version=9p2000.L,ro,msize=512000,cache=loose hostroot /lower || fail "no hostroot share"
mount -t tmpfs -o size=60% rw /rw && mkdir -p /rw/upper /rw/work
mount -t overlay overlay -o lowerdir=/lower,upperdir=/rw/upper,workdir=/rw/work /newroot || fail "overlay failed"
R=/newroot
for d in proc sys dev; do umount $R/$d 2>/dev/null; done
mount -t proc proc $R/proc; mount -t sysfs sys $R/sys; mount -t devtmpfs dev $R/dev
mkdir -p $R/dev/pts $R/dev/shm; mount -t devpts devpts $R/dev/pts; mount -t tmpfs shm $R/dev/shm
mount -t tmpfs run $R/run
mkdir -p "$R$vcan_out" && mount -t 9p -o trans=virtio,version=9p2000.L,msize=512000 vcanout "$R$vcan_out" || fail "no vcanout share"
mkdir -p "$R/lib/modules/$vcan_kver" && mount --bind "$R$vcan_work/kernel/lib/modules/$vcan_kver" "$R/lib/modules/$vcan_kver"
hostname vcan-guest
chroot $R /bin/bash "$vcan_out/.stage2.sh"
sync
poweroff -f
EOF
    chmod +x "$root/init"
    ( cd "$root" && find . | cpio -o -H newc --quiet | gzip -1 > "$WORK/initramfs.cpio.gz" )
}

write_stage2() {
    # runs inside the guest, chrooted into the host's (overlaid) root filesystem
    cat > "$OUT/.stage2.sh" <<EOF
#!/bin/bash
export PATH='$PATH' HOME=/root LANG=C.UTF-8 TERM=dumb
cd '$OUT'
{
  modprobe -a vcan can-raw can-bcm can-gw || echo "stage2: modprobe failed"
  for i in $IFACES; do ip link add dev \$i type vcan && ip link set up \$i; done
  echo "stage2: kernel \$(uname -r), \$(nproc) cpu(s), clocksource \$(cat /sys/devices/system/clocksource/clocksource0/current_clocksource), up \$(cut -d' ' -f1 /proc/uptime) s"
  ip -brief link show type vcan
} 2>&1 | tee '$OUT/setup.log'
cd '$PWD' 2>/dev/null || cd /
bash '$OUT/.cmd.sh' 2>&1 | tee '$OUT/output.log'
echo \${PIPESTATUS[0]} > '$OUT/rc'
sync
EOF
}

cmd_run() {
    local KVER cpu kernel
    KVER=$(kver)
    kernel="$WORK/kernel/boot/vmlinux-$KVER"; [ -f "$kernel" ] || kernel="$WORK/kernel/boot/vmlinuz-$KVER"
    [ -f "$WORK/initramfs.cpio.gz" ] || die "no initramfs: run '$0 setup'"
    mkdir -p "$OUT"; rm -f "$OUT/output.log" "$OUT/rc" "$OUT/setup.log"
    write_stage2
    case "$ACCEL" in
        tcg) cpu=max ;;
        # PVM-backed /dev/kvm (nested sandboxes) rejects these MSR/instructions of a stock kernel
        kvm) cpu=host,-arch-capabilities,-cx16 ;;
        *) die "VCAN_ACCEL must be tcg or kvm" ;;
    esac
    local t0=$SECONDS
    timeout "$TIMEOUT" qemu-system-x86_64 -accel "$ACCEL" -cpu "$cpu" -m "$MEM" -smp "$SMP" \
        -nographic -no-reboot -nic none \
        -kernel "$kernel" -initrd "$WORK/initramfs.cpio.gz" \
        -append "console=ttyS0 quiet panic=-1 vcan_work=$WORK vcan_kver=$KVER vcan_out=$OUT $APPEND_EXTRA" \
        -virtfs local,path=/,mount_tag=hostroot,security_model=none,readonly=on,multidevs=remap \
        -virtfs "local,path=$OUT,mount_tag=vcanout,security_model=none,multidevs=remap" \
        </dev/null || echo "vcan-guest: qemu exited with $?" >&2
    echo "vcan-guest: guest ran $((SECONDS - t0)) s (boot + command + power-off)" >&2
    [ -f "$OUT/rc" ] || die "no exit status from the guest (see console output above)"
    return "$(cat "$OUT/rc")"
}

case "${1:-}" in
    setup) cmd_setup ;;
    run) shift; [ $# -gt 0 ] || die "run: no command"; mkdir -p "$OUT"; printf '%s\n' "$*" > "$OUT/.cmd.sh"; cmd_run ;;
    run-file) shift; [ -f "${1:-}" ] || die "run-file: no such file"; mkdir -p "$OUT"; cp "$1" "$OUT/.cmd.sh"; cmd_run ;;
    initramfs) build_initramfs "$(kver)" ;;
    *) sed -n '2,/^set -euo/p' "$0" | sed '$d'; exit 2 ;;
esac
