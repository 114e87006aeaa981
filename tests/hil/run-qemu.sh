#!/bin/sh
# Hardware in the loop without hardware: boots Debian's own kernel (the linux-image-6.1.0-*-amd64
# package that linux-image-amd64 depends on) under qemu, with the CAN modules and a virtual CAN
# interface, and runs test scripts there against the real kernel's SocketCAN (see
# tests/hil/README.md).
#
# The VM has no network device at all (-nic none). The host's root directory is shared into it
# read-only over 9p (virtio) and the tests run chrooted into it, so build-tree binaries run
# unchanged, at the same absolute paths. Inside the VM: vcan0 (up) and vcan1 (down) exist, lo is
# up with the multicast route LCM needs, /tmp, /run and /dev/shm are private tmpfs, and every
# script runs with these variables set:
#   MRROC_SOURCE_DIR  the source tree          MRROC_BUILD_DIR  the build tree
#   MRROC_BIN_DIR     the build tree's bin/    MRROC_CAN_IFACE  vcan0 (up)
#   MRROC_CAN_DOWN_IFACE  vcan1 (administratively down)
# The VM prints "MRROC-HIL-RESULT: PASS" when every script exited 0, else "MRROC-HIL-RESULT:
# FAIL ...", and powers off.
#
# Usage: tests/hil/run-qemu.sh BUILD_DIR [SCRIPT...]
#   SCRIPT: shell scripts run in the VM one after the other with sh (default: tests/hil/vm-tests.sh).
# Environment: MRROC_HIL_TIMEOUT (seconds until qemu is killed, default 240),
#   MRROC_HIL_CACHE (where the kernel package is downloaded and unpacked, default
#   BUILD_DIR/hil-cache), MRROC_HIL_KEEP=1 keeps the run directory (initramfs, console log),
#   MRROC_HIL_KVM=1 uses KVM instead of software emulation (nested KVM on the project's VMs
#   hangs the guest, so it is off by default; software emulation takes a few seconds).
# Exit codes: 0 pass, 1 fail, 77 skipped (no qemu, no busybox-static, kernel package not
# obtainable); the reason is printed.
set -eu

skip() {
  echo "hil: SKIP: $*"
  exit 77
}
fail() {
  echo "hil: FAIL: $*"
  exit 1
}

[ $# -ge 1 ] || { echo "usage: $0 BUILD_DIR [SCRIPT...]" >&2; exit 2; }
source_dir=$(cd "$(dirname "$0")/../.." && pwd)
build_dir=$(cd "$1" && pwd)
shift
if [ $# -eq 0 ]; then set -- "$source_dir/tests/hil/vm-tests.sh"; fi
scripts=""
for s in "$@"; do
  [ -f "$s" ] || fail "no such test script: $s"
  s=$(cd "$(dirname "$s")" && pwd)/$(basename "$s")
  case $(basename "$s") in *[!A-Za-z0-9_.+-]*) fail "test script name has characters the VM's init cannot quote: $s" ;; esac
  scripts="$scripts $s"
done
case $source_dir$build_dir in *[!A-Za-z0-9_./+-]*) fail "source or build path has unusual characters: $source_dir $build_dir" ;; esac
timeout_s=${MRROC_HIL_TIMEOUT:-240}
cache=${MRROC_HIL_CACHE:-$build_dir/hil-cache}
started=$(date +%s)

# ---- Tools ----
command -v qemu-system-x86_64 >/dev/null 2>&1 ||
  skip "qemu-system-x86_64 not found (Debian package qemu-system-x86; scripts/install-deps installs it)"
busybox=""
for b in /bin/busybox /usr/bin/busybox; do
  # Only a static busybox runs in the initramfs, which has no libraries.
  if [ -x "$b" ] && ! ldd "$b" >/dev/null 2>&1; then busybox=$b; break; fi
done
[ -n "$busybox" ] || skip "no statically linked busybox (Debian package busybox-static; scripts/install-deps installs it)"
for tool in cpio gzip dpkg-deb flock timeout; do
  command -v "$tool" >/dev/null 2>&1 || skip "$tool not found"
done

# ---- The kernel: downloaded once per cache directory, only the parts the VM needs kept ----
mkdir -p "$cache"
exec 9>"$cache/.lock"
flock 9  # two runs in one build tree at once: one downloads, the other waits
resolve_kernel() {
  apt-cache depends linux-image-amd64 2>/dev/null |
    awk '$1 == "Depends:" && $2 ~ /^linux-image-[0-9].*-amd64$/ { print $2; exit }'
}
package=$(resolve_kernel)
if [ -z "$package" ] && [ "$(id -u)" = 0 ] && ! ls "$cache"/linux-image-*/.unpacked >/dev/null 2>&1; then
  # A fresh machine whose package lists were never downloaded.
  echo "hil: apt-cache does not know linux-image-amd64; running apt-get update"
  apt-get update -qq >"$cache/update.log" 2>&1 || true
  package=$(resolve_kernel)
fi
if [ -z "$package" ]; then
  # No package lists (apt-get update never ran): use a kernel downloaded earlier, if any.
  package=$(ls -d "$cache"/linux-image-*/.unpacked 2>/dev/null | sort -V | tail -n 1 | xargs -r dirname | xargs -r basename)
  [ -n "$package" ] || skip "apt-cache cannot resolve linux-image-amd64 (run apt-get update) and no kernel is cached in $cache"
fi
kdir=$cache/$package
if [ ! -f "$kdir/.unpacked" ]; then
  echo "hil: downloading $package into $cache"
  rm -rf "$kdir" "$cache"/*.deb
  if ! (cd "$cache" && apt-get download "$package") >"$cache/download.log" 2>&1; then
    skip "apt-get download $package failed: $(tail -n 3 "$cache/download.log" | tr '\n' ' ')"
  fi
  deb=$(ls "$cache"/"$package"_*.deb | head -n 1)
  mkdir -p "$kdir.tmp"
  # dpkg-deb -x of the whole package is 400 MB; the VM needs the kernel and a few module folders.
  dpkg-deb --fsys-tarfile "$deb" | tar -x -C "$kdir.tmp" --wildcards \
    './boot/vmlinuz-*' './boot/config-*' \
    './lib/modules/*/kernel/net/can/*' './lib/modules/*/kernel/drivers/net/can/*' \
    './lib/modules/*/kernel/drivers/virtio/*' './lib/modules/*/kernel/net/9p/*' \
    './lib/modules/*/kernel/fs/9p/*' './lib/modules/*/kernel/fs/netfs/*' \
    './lib/modules/*/kernel/fs/fscache/*'
  rm -f "$deb"
  rm -rf "$kdir"
  mv "$kdir.tmp" "$kdir"
  touch "$kdir/.unpacked"
  for old in "$cache"/linux-image-*; do  # kernels of earlier runs
    [ "$old" = "$kdir" ] || rm -rf "$old"
  done
fi
flock -u 9
vmlinuz=$(ls "$kdir"/boot/vmlinuz-* | head -n 1)
modules=$(ls -d "$kdir"/lib/modules/*/kernel | head -n 1)
kernel_version=$(basename "$(dirname "$modules")")

# ---- Modules, in dependency order (from each module's .modinfo "depends=") ----
find_module() {  # name -> path (module names use - and _ interchangeably)
  n1=$(echo "$1" | tr - _)
  n2=$(echo "$1" | tr _ -)
  find "$modules" \( -name "$n1.ko" -o -name "$n2.ko" \) | head -n 1
}
ordered=""
add_module() {  # adds the module's dependencies, then the module
  path=$(find_module "$1")
  [ -n "$path" ] || fail "module $1 not found in $modules"
  case " $ordered " in *" $path "*) return 0 ;; esac
  deps=$("$busybox" strings "$path" | sed -n 's/^depends=//p' | tr , ' ')
  for d in $deps; do add_module "$d"; done
  path=$(find_module "$1")  # add_module recursion reuses the variable
  case " $ordered " in *" $path "*) ;; *) ordered="$ordered $path" ;; esac
}
for m in virtio_pci 9pnet_virtio 9p can can-raw can-dev vcan; do
  # Built into the kernel (=y in its config) needs no module.
  add_module "$m"
done

# ---- The initramfs ----
run_dir=$(mktemp -d "$build_dir/hil-run.XXXXXX")
if [ "${MRROC_HIL_KEEP:-0}" != 1 ]; then trap 'rm -rf "$run_dir"' EXIT; fi
root=$run_dir/initramfs
mkdir -p "$root/bin" "$root/modules" "$root/proc" "$root/sys" "$root/dev" "$root/host"
cp "$busybox" "$root/bin/busybox"
: >"$root/modules/order"
for path in $ordered; do
  cp "$path" "$root/modules/"
  basename "$path" >>"$root/modules/order"
done
# The scripts travel in the initramfs (the VM's /tmp is its own) and appear in the chroot under
# /run/mrroc-hil/NN-NAME.
mkdir -p "$root/scripts"
vm_scripts=""
n=0
for s in $scripts; do
  n=$((n + 1))
  name=$(printf '%02d-%s' "$n" "$(basename "$s")")
  cp "$s" "$root/scripts/$name"
  vm_scripts="$vm_scripts /run/mrroc-hil/$name"
done
# /tmp and /var/tmp of the VM are private tmpfs, unless the source or build tree lies below one
# of them (then it stays the host's, read-only, and TMPDIR points to /dev/shm).
private_tmp=""
vm_tmp=/tmp
for d in /tmp /var/tmp; do
  case "$source_dir/ $build_dir/" in
    "$d"/*|*" $d"/*) [ "$d" != /tmp ] || vm_tmp=/dev/shm ;;
    *) private_tmp="$private_tmp $d" ;;
  esac
done
cat >"$root/init" <<EOF
#!/bin/busybox sh
/bin/busybox --install -s /bin
export PATH=/bin
result() { echo "MRROC-HIL-RESULT: \$*"; sync; poweroff -f; sleep 10; }
mount -t proc proc /proc
mount -t sysfs sysfs /sys
mount -t devtmpfs devtmpfs /dev
for m in \$(cat /modules/order); do
  insmod /modules/\$m || result "FAIL (insmod \$m)"
done
echo "hil: kernel \$(uname -r), modules loaded: \$(cat /modules/order | tr '\n' ' ')"
mount -t 9p -o trans=virtio,version=9p2000.L,ro,msize=262144,cache=loose hostroot /host ||
  result "FAIL (cannot mount the host's root over 9p)"
mount -t proc proc /host/proc
mount -t sysfs sysfs /host/sys
mount -t devtmpfs devtmpfs /host/dev
mkdir -p /host/dev/pts /host/dev/shm
mount -t devpts devpts /host/dev/pts
mount -t tmpfs tmpfs /host/dev/shm
mount -t tmpfs tmpfs /host/run
for d in $private_tmp; do mount -t tmpfs tmpfs /host\$d; done
chmod 1777 /host/dev/shm
for d in $private_tmp; do chmod 1777 /host\$d; done
mkdir -p /host/run/mrroc-hil
mount -o bind /scripts /host/run/mrroc-hil
ip link set lo up
ip route add 224.0.0.0/4 dev lo
ip link add dev vcan0 type vcan || result "FAIL (ip link add vcan0 type vcan)"
ip link set vcan0 up || result "FAIL (ip link set vcan0 up)"
ip link add dev vcan1 type vcan || result "FAIL (ip link add vcan1 type vcan)"
echo "hil: vcan0 up, vcan1 down; running:$scripts"
rc=0
for s in $vm_scripts; do
  echo "hil: === \$s ==="
  chroot /host /usr/bin/env -i PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin \
    HOME=$vm_tmp TMPDIR=$vm_tmp LANG=C.UTF-8 MRROC_IN_NETNS=1 MRROC_IN_HIL_VM=1 \
    MRROC_SOURCE_DIR=$source_dir MRROC_BUILD_DIR=$build_dir MRROC_BIN_DIR=$build_dir/bin \
    MRROC_CAN_IFACE=vcan0 MRROC_CAN_DOWN_IFACE=vcan1 \
    /bin/sh -c 'cd "\$MRROC_BUILD_DIR" && exec /bin/sh "\$0"' \$s
  s_rc=\$?
  echo "hil: \$s exited with \$s_rc"
  [ \$s_rc = 0 ] || rc=\$s_rc
done
if [ \$rc = 0 ]; then result PASS; else result "FAIL (a test script exited with \$rc)"; fi
EOF
chmod +x "$root/init"
(cd "$root" && find . | cpio -o -H newc --quiet | gzip -1) >"$run_dir/initrd.gz"

# ---- Boot ----
# KVM where it can be used, else software emulation (-accel tries them in order).
accel="-accel tcg -cpu max"
if [ "${MRROC_HIL_KVM:-0}" = 1 ]; then accel="-accel kvm -cpu host,-arch-capabilities"; fi
log=$run_dir/console.log
echo "hil: booting $kernel_version ($(basename "$vmlinuz")), timeout ${timeout_s} s, $accel"
booted=$(date +%s)
rc=0
# shellcheck disable=SC2086
timeout -k 5 "$timeout_s" qemu-system-x86_64 $accel -smp 2 -m 512 \
  -nographic -no-reboot -nic none -monitor none -serial stdio \
  -kernel "$vmlinuz" -initrd "$run_dir/initrd.gz" \
  -append "console=ttyS0 quiet panic=-1 rdinit=/init" \
  -virtfs local,path=/,mount_tag=hostroot,security_model=none,readonly=on,multidevs=remap \
  </dev/null >"$log" 2>&1 || rc=$?
ended=$(date +%s)
tr -d '\r' <"$log"
echo "hil: VM ran $((ended - booted)) s (qemu exit code $rc); $((ended - started)) s in all"
if [ $rc = 124 ] || [ $rc = 137 ]; then fail "the VM did not finish within $timeout_s s (killed)"; fi
if grep -q '^MRROC-HIL-RESULT: PASS' "$log"; then
  echo "hil: PASS"
  exit 0
fi
line=$(tr -d '\r' <"$log" | grep '^MRROC-HIL-RESULT:' | tail -n 1)
[ -n "$line" ] || line="no result line on the console of the VM (qemu exit code $rc)"
fail "$line"
