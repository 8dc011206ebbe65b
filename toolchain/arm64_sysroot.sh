#!/usr/bin/env bash
# Makes the arm64 sysroot the cross build links against: Debian 12's arm64 packages named
# `arm64-sysroot` in toolchain/packages.txt, with everything they depend on, unpacked (not
# installed) into one folder.
#
#   toolchain/arm64_sysroot.sh SYSROOT
#
# Why not multiarch (`dpkg --add-architecture arm64` and the `:arm64` packages beside the
# machine's own): on bookworm the two cannot be installed together for what calbox links.
# libopencv-imgcodecs406:arm64 needs libgdal32:arm64, which replaces the amd64 one and takes the
# machine's libopencv-dev with it; libapriltag-dev:arm64 ships a CMake file that differs from the
# amd64 one at the same path; libopencv-dev, the package holding OpenCV's CMake configuration, is
# not Multi-Arch at all. A sysroot keeps the machine's own packages untouched.
#
# apt resolves and fetches with a state of its own (an empty dpkg status, arm64 only), from the
# machine's sources and keys; the packages are then unpacked with dpkg -x. Re-run when the list
# changes: the folder is rebuilt whole, never half-updated.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
sysroot="$(realpath -m "${1:?usage: arm64_sysroot.sh SYSROOT}")"

mapfile -t packages < <(awk '$1 == "arm64-sysroot" { print $2 }' "$here/packages.txt")
[ ${#packages[@]} -gt 0 ] || { echo "arm64_sysroot.sh: no arm64-sysroot packages listed" >&2; exit 1; }
stamp="$( (printf "%s\n" "${packages[@]}"; cat "${BASH_SOURCE[0]}") | sha256sum | cut -c1-16)"
if [ -f "$sysroot/.calbox-sysroot" ] && [ "$(cat "$sysroot/.calbox-sysroot")" = "$stamp" ]; then
    exit 0
fi

state="$sysroot.apt"
mkdir -p "$state/lists/partial" "$state/archives/partial" "$state/etc/preferences.d"
: > "$state/status"
apt_options=(
    -o "APT::Architecture=arm64" -o "APT::Architectures=arm64"
    -o "Dir::State=$state" -o "Dir::State::Lists=$state/lists" -o "Dir::State::status=$state/status"
    -o "Dir::Cache=$state" -o "Dir::Cache::Archives=$state/archives"
    -o "Dir::Etc::Preferences=$state/etc/preferences" -o "Dir::Etc::PreferencesParts=$state/etc/preferences.d"
    -o "APT::Install-Recommends=false" -o "Debug::NoLocking=true"
)
echo "arm64_sysroot.sh: fetching ${#packages[@]} packages and their dependencies for arm64"
apt-get "${apt_options[@]}" update -qq
apt-get "${apt_options[@]}" install -y -qq --download-only "${packages[@]}" > "$state/fetch.log"

partial="$sysroot.partial"
rm -rf "$partial" && mkdir -p "$partial"
for deb in "$state"/archives/*.deb; do
    dpkg-deb -x "$deb" "$partial"
done
# Some libraries are reached through update-alternatives, which their maintainer scripts would
# set up on an installed system (libblas.so.3 and liblapack.so.3, which OpenCV's dependencies
# need): the links are made here as those scripts make them by default.
for deb in "$state"/archives/*.deb; do
    { dpkg-deb -I "$deb" postinst 2>/dev/null || true; } | sed -e ':a' -e '/\\$/N; s/\\\n//; ta' |
        awk '$1 == "update-alternatives" && $2 == "--install" && $3 ~ /^\/usr\/lib\// { print $3, $5 }'
done | while read -r link target; do
    ln -sfn "$target" "$partial$link"
done
# Links to absolute paths would leave the sysroot for the machine's own files.
find "$partial" -type l -lname '/*' | while read -r link; do
    target="$(readlink "$link")"
    ln -sfn "$(realpath -m --relative-to="$(dirname "$link")" "$partial$target")" "$link"
done
# What each library's package says a binary linking it depends on (its shlibs file: library,
# version, dependency): the cross-built package's Depends come from it (cmake/cross_package_depends.cmake),
# as dpkg-shlibdeps makes them from the installed packages' files on a native build.
for deb in "$state"/archives/*.deb; do
    { dpkg-deb -I "$deb" shlibs 2>/dev/null || true; }
done | awk '$1 !~ /:$/ && NF >= 3' > "$partial/.calbox-shlibs"
echo "$stamp" > "$partial/.calbox-sysroot"
rm -rf "$sysroot" && mv "$partial" "$sysroot"
echo "arm64_sysroot.sh: $(ls "$state"/archives/*.deb | wc -l) packages unpacked into $sysroot"
