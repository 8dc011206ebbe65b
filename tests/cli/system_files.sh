#!/bin/bash
# The Raspberry Pi board's system files: the service's exposure as systemd scores it with the
# network allowed (README: 1.4, the goal 2.0 or lower), the unit as `systemd-analyze verify` reads
# it (its ExecStart pointed at this build's binary, the rest as shipped), systemd's supervision
# (Type=notify, a watchdog), and the udev rules' and config.txt's lines as the README lists them.
# Usage: system_files.sh SOURCE_DIR CALBOX_BINARY
set -eu
top="$1"
binary="$2"
unit="$top/board/rpi/system/calbox.service"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
sed "s|^ExecStart=/usr/bin/calbox |ExecStart=$binary |" "$unit" > "$work/calbox.service"
grep -q "^ExecStart=$binary run --board rpi " "$work/calbox.service"
systemd-analyze verify "$work/calbox.service" || { echo "FAIL: systemd-analyze verify"; exit 1; }
grep -q '^Type=notify$' "$unit"
grep -q '^NotifyAccess=main$' "$unit"
grep -q '^WatchdogSec=[0-9]*s$' "$unit"
score=$(systemd-analyze security --offline=true "$unit" 2>&1 | sed -n 's/.*Overall exposure level for calbox.service: \([0-9.]*\) .*/\1/p')
[ -n "$score" ] || { echo "FAIL: no exposure level from systemd-analyze"; exit 1; }
awk -v s="$score" 'BEGIN { exit !(s <= 1.4) }' || { echo "FAIL: exposure $score, README says 1.4"; exit 1; }
# The network a host link and Modbus TCP need is open, to the local ranges only.
grep -q '^RestrictAddressFamilies=AF_UNIX AF_NETLINK AF_INET AF_INET6$' "$unit"
grep -q '^IPAddressDeny=any$' "$unit"
grep -q '^IPAddressAllow=localhost link-local 10.0.0.0/8 172.16.0.0/12 192.168.0.0/16 fc00::/7$' "$unit"
if grep -q '^PrivateNetwork=yes' "$unit"; then echo "FAIL: the unit has no network"; exit 1; fi
grep -q '^DevicePolicy=closed$' "$unit"
grep -q '^User=calbox$' "$unit"
grep -q '^ExecStart=/usr/bin/calbox run --board rpi ' "$unit"
rules="$top/board/rpi/system/60-calbox.rules"
for group in gpio i2c video; do grep -q "GROUP=\"$group\", MODE=\"0660\"" "$rules"; done
for line in camera_auto_detect=1 dtparam=i2c_arm=on enable_uart=1 dtoverlay=disable-bt; do
    grep -q "^$line$" "$top/board/rpi/system/config.txt"
done
echo "system files: exposure $score"
