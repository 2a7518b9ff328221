#!/usr/bin/env bash
# photos.sh DIR: the flow benchmark's source photographs, from Debian's
# mate-backgrounds package (nature photographs, 1280-2560 px wide), as
# 8-bit grey PNGs 1280 px wide in DIR. Needs apt-get and ffmpeg
# (../shared/peers/setup.sh installs ffmpeg). Safe to run again.
set -euo pipefail
dir=${1:?usage: photos.sh DIR}
mkdir -p "$dir"
names="Aqua Blinds Dune Garden GreenMeadow LadyBird Storm Wood"
missing=0
for n in $names; do [ -f "$dir/$n.png" ] || missing=1; done
[ "$missing" = 0 ] && exit 0
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
(cd "$tmp" && apt-get download mate-backgrounds >/dev/null 2>&1) || {
  apt-get update >/dev/null && (cd "$tmp" && apt-get download mate-backgrounds >/dev/null)
}
dpkg-deb -x "$tmp"/mate-backgrounds_*.deb "$tmp/x"
for n in $names; do
  ffmpeg -v error -y -i "$tmp/x/usr/share/backgrounds/mate/nature/$n.jpg" \
    -vf "scale=1280:-2:flags=area,format=gray" "$dir/$n.png"
done
echo "photos in $dir: $names"
