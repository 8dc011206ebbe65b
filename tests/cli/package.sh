#!/bin/bash
# The Debian package (docs/devices.md, Installing): built twice by CPack from this build (two versions),
# installed, upgraded, removed and purged by dpkg in a throwaway root. The maintainer scripts
# run there without a chroot and, seeing DPKG_ROOT, touch only files; what they do on a real
# system (user, groups, udev, systemd) is checked by reading them.
# Arguments: BUILD_DIR SOURCE_DIR [EMULATOR...] (the cross build's, to run the installed binary).
set -eu
build="$1"
top="$2"
shift 2
emulator=("$@")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for version in 0.1.0 0.1.1; do
    cpack --config "$build/CPackConfig.cmake" -G DEB -B "$work/pkg-$version" \
        -D CPACK_PACKAGE_VERSION="$version" -D CPACK_DEBIAN_PACKAGE_VERSION="$version" > "$work/cpack-$version.log"
done
deb1=$(ls "$work"/pkg-0.1.0/calbox_0.1.0_*.deb)
deb2=$(ls "$work"/pkg-0.1.1/calbox_0.1.1_*.deb)
contents=$(dpkg-deb --contents "$deb1")
for f in ./usr/bin/calbox ./usr/lib/systemd/system/calbox.service ./usr/lib/udev/rules.d/60-calbox.rules \
         ./etc/calbox/board.toml ./usr/share/doc/calbox/config.txt; do
    grep -q " $f\$" <<< "$contents" || { echo "FAIL: $f not in the package"; exit 1; }
done
if grep -q "var/lib/calbox" <<< "$contents"; then echo "FAIL: the package holds the records' directory"; exit 1; fi
dpkg-deb --info "$deb1" | grep -q "Depends:.*adduser"
# Depends: from dpkg-shlibdeps natively, from the sysroot's shlibs files in the cross build.
dpkg-deb --info "$deb1" | grep -q "Depends:.*libopencv-core406 (>= 4.6.0"
dpkg-deb --info "$deb1" | grep -q "Depends:.*libgpiod2"
dpkg-deb --info "$deb1" | grep -q "Depends:.*libmodbus5"
dpkg-deb --info "$deb1" | grep -q "Depends:.*libc6 (>= "
binary_arch=$(dpkg-deb --field "$deb1" Architecture)
elf_machine=$(od -An -tu2 -j18 -N2 "$build/calbox" | tr -d ' ')   # ELF e_machine
case "$elf_machine:$binary_arch" in
    183:arm64|62:amd64) ;;
    *) echo "FAIL: a package for $binary_arch holds a binary for ELF machine $elf_machine"; exit 1 ;;
esac
[ "$(dpkg-deb --ctrl-tarfile "$deb1" | tar -xO ./conffiles)" = "/etc/calbox/board.toml" ]
for script in postinst prerm postrm; do sh -n "$top/board/rpi/system/debian/$script"; done
grep -q "adduser --quiet --system --group --home /var/lib/calbox" "$top/board/rpi/system/debian/postinst"
grep -q "for group in video gpio i2c dialout" "$top/board/rpi/system/debian/postinst"

root="$work/root"
mkdir -p "$root/var/lib/dpkg/info" "$root/var/lib/dpkg/updates" "$root/var/lib/dpkg/triggers"
touch "$root/var/lib/dpkg/status" "$root/var/lib/dpkg/available"
if [ "$binary_arch" != "$(dpkg --print-architecture)" ]; then
    dpkg --root="$root" --add-architecture "$binary_arch"
fi
dpkg_in_root() { dpkg --root="$root" --force-script-chrootless --force-depends --log=/dev/null "$@" > "$work/dpkg.log" 2>&1 || { cat "$work/dpkg.log"; exit 1; }; }
dpkg_in_root -i "$deb1"
[ -x "$root/usr/bin/calbox" ]
"${emulator[@]}" "$root/usr/bin/calbox" --help > /dev/null
# The owner changes the board file and the box keeps records; the upgrade keeps both.
sed -i 's|^v4l2_device = .*|v4l2_device = "/dev/video2"|' "$root/etc/calbox/board.toml"
mkdir -p "$root/var/lib/calbox/records"
echo kept > "$root/var/lib/calbox/records/cycle-0001.txt"
dpkg_in_root -i "$deb2"
grep -q "^Version: 0.1.1" <(dpkg --root="$root" -s calbox)
grep -q '^v4l2_device = "/dev/video2"' "$root/etc/calbox/board.toml"
[ "$(cat "$root/var/lib/calbox/records/cycle-0001.txt")" = kept ]
# Removed: the binary goes, the board file (a conffile) and the records stay; purged: the board
# file goes too, the records stay.
dpkg_in_root --remove calbox
[ ! -e "$root/usr/bin/calbox" ] && [ -e "$root/etc/calbox/board.toml" ] && [ -e "$root/var/lib/calbox/records/cycle-0001.txt" ]
dpkg_in_root --purge calbox
[ ! -e "$root/etc/calbox/board.toml" ] && [ -e "$root/var/lib/calbox/records/cycle-0001.txt" ]
echo "package: installed, upgraded (board file and records kept), removed and purged"
