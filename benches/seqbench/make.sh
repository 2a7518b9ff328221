#!/usr/bin/env bash
# make.sh DIR: the encoder's development set, Y4M sequences of kinds the
# three shared sequences do not cover, made from real photographs (Debian's
# mate-backgrounds package) under synthetic camera motion and from ffmpeg's
# own sources. Needs apt-get and ffmpeg (../shared/peers/setup.sh installs
# ffmpeg). Safe to run again: sequences already in DIR are kept.
#
# Camera motion is rendered at 4x the output size and reduced with an area
# filter, so pans and zooms move by quarter pixels and carry a camera's
# anti-aliasing; zoom is a per-frame rescale of the photograph.
#
# | name | size | what |
# |---|---|---|
# | static_noise_cif | 352x288 | fixed camera, sensor noise, two small movers |
# | cuts_cif | 352x288 | three shots (pan, zoom, shake) joined by hard cuts |
# | fastpan_cif | 352x288 | diagonal pan of 10 and 4 px a frame |
# | dark_cif | 352x288 | dim, low-contrast, noisy; slow pan and zoom out |
# | light_cif | 352x288 | slow pan while the light rises from dark |
# | handheld_vga | 640x480 | hand-held shake, drift and zoom in |
# | cartoon_cif | 352x288 | flat-coloured graphic art panning, flat shapes crossing it |
# | testsrc2_qcif | 176x144 | ffmpeg's testsrc2 animation |
# | garden_720p | 1280x720 | slow pan and zoom, 30 frames |
set -euo pipefail
dir=${1:?usage: make.sh DIR}
mkdir -p "$dir"
FF="ffmpeg -v error -y -nostdin"
src=$dir/.photos
if [ ! -d "$src/usr/share/backgrounds/mate" ]; then
  tmp=$(mktemp -d)
  trap 'rm -rf "$tmp"' EXIT
  (cd "$tmp" && apt-get download mate-backgrounds >/dev/null 2>&1) || {
    apt-get update >/dev/null && (cd "$tmp" && apt-get download mate-backgrounds >/dev/null)
  }
  mkdir -p "$src"
  dpkg-deb -x "$tmp"/mate-backgrounds_*.deb "$src"
fi
photos=$src/usr/share/backgrounds/mate
out() { echo "$dir/$1.y4m"; }
have() { [ -s "$(out "$1")" ]; }

# camera PHOTO W H FRAMES X Y ZOOM_PER_FRAME [EXTRA_FILTERS [COVER]]: a
# camera over PHOTO at X, Y output pixels from the centre (expressions of
# the frame number n), zooming by ZOOM_PER_FRAME, then EXTRA_FILTERS
# (after the reduction), as raw 4:2:0 video on stdout. The photograph is
# first scaled to COVER (default 2) times the window: the path must stay
# inside it, since crop clamps (the camera would stop).
camera() {
  local photo=$1 w=$2 h=$3 frames=$4 vx=$5 vy=$6 zoom=$7 extra=${8:-null} cover=${9:-2}
  local cw=$((4 * w)) ch=$((4 * h))
  $FF -loop 1 -framerate 30 -i "$photo" -filter_complex "
    scale=w='max($cover*$cw,$cover*$ch*iw/ih)':h=-2,
    scale=w='trunc(iw*(1+($zoom)*n)/2)*2':h=-2:eval=frame,
    crop=$cw:$ch:x='(iw-$cw)/2+4*($vx)':y='(ih-$ch)/2+4*($vy)',
    scale=$w:$h:flags=area,$extra,format=yuv420p" \
    -frames:v "$frames" -f rawvideo -
}

# y4m NAME W H: raw 4:2:0 frames on stdin to DIR/NAME.y4m (written
# elsewhere first, so a failed run leaves no complete-looking file).
y4m() {
  local f
  f=$(out "$1")
  $FF -f rawvideo -pix_fmt yuv420p -s "$2x$3" -r 30 -i - -f yuv4mpegpipe "$f.part"
  mv "$f.part" "$f"
}

have static_noise_cif || {
  # Two 40x32 movers cut from another photograph, crossing at 1.5 and
  # 0.75 px a frame.
  $FF -loop 1 -framerate 30 -i "$photos/nature/GreenMeadow.jpg" \
    -loop 1 -framerate 30 -i "$photos/nature/LadyBird.jpg" -filter_complex "
    [0]scale=352:288:flags=area[bg];
    [1]scale=320:-2,split[a][b];
    [a]crop=40:32:140:80[m1];[b]crop=32:40:60:120[m2];
    [bg][m1]overlay=x='40+1.5*n':y=200[t];
    [t][m2]overlay=x=260:y='30+0.75*n',noise=alls=5:allf=t,format=yuv420p" \
    -frames:v 60 -f rawvideo - | y4m static_noise_cif 352 288
}

have cuts_cif || {
  {
    camera "$photos/nature/Aqua.jpg" 352 288 20 "3*n" 0 0
    camera "$photos/nature/Storm.jpg" 352 288 20 0 0 0.01
    camera "$photos/abstract/Elephants.jpg" 352 288 20 "2*sin(n/2)" "1.5*cos(n/3)" 0
  } | y4m cuts_cif 352 288
}

have fastpan_cif || camera "$photos/nature/Wood.jpg" 352 288 60 "10*n-300" "4*n-120" 0 null 3 |
  y4m fastpan_cif 352 288

have dark_cif || camera "$photos/nature/RainDrops.jpg" 352 288 60 "0.75*n" "0.25*n" -0.002 \
  "eq=brightness=-0.25:contrast=0.55:gamma=0.8,noise=alls=6:allf=t" | y4m dark_cif 352 288

have light_cif || camera "$photos/nature/TwoWings.jpg" 352 288 60 "-1.25*n" 0 0 \
  "eq=brightness='-0.35+0.006*n':eval=frame" | y4m light_cif 352 288

have handheld_vga || camera "$photos/nature/YellowFlower.jpg" 640 480 60 \
  "1.5*n+6*sin(n/2.5)" "5*cos(n/3.1)" 0.002 | y4m handheld_vga 640 480

have cartoon_cif || {
  # Flat shapes (colour sources) crossing graphic art that pans.
  camera "$photos/desktop/Ubuntu-Mate-Warm-no-logo.png" 352 288 60 "2*n" 0 0 |
    $FF -f rawvideo -pix_fmt yuv420p -s 352x288 -r 30 -i - \
      -f lavfi -i "color=c=0x2060c0:s=64x48:r=30" -f lavfi -i "color=c=0xf0d020:s=36x36:r=30" \
      -filter_complex "[0][1]overlay=x='20+4*n':y='60+n':shortest=1[t];
        [t][2]overlay=x='300-5*n':y='200-2*n':shortest=1,format=yuv420p" \
      -frames:v 60 -f rawvideo - | y4m cartoon_cif 352 288
}

have testsrc2_qcif || $FF -f lavfi -i "testsrc2=s=176x144:r=30" -frames:v 60 -pix_fmt yuv420p -f rawvideo - |
  y4m testsrc2_qcif 176 144

have garden_720p || camera "$photos/nature/Garden.jpg" 1280 720 30 "1.5*n" "-0.5*n" 0.003 | y4m garden_720p 1280 720

ls "$dir"/*.y4m
