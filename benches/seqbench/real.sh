#!/usr/bin/env bash
# real.sh DIR [N]: more real camera footage for the development sets, of the
# kinds ../shared/data/real/fetch.sh lacks (hand-held and moving cameras,
# 720p and 1080p), taken from files that Debian packages ship, as 8-bit
# 4:2:0 Y4M (the first N frames, default 90) in DIR. Nothing of it is
# committed: it is fetched. Needs apt-get, dpkg-deb and ffmpeg. Safe to run
# again: a Y4M already in DIR is kept.
#
# SET=kinds real.sh DIR [N]: instead, four clips of kinds that neither
# set has, to check what the sets say on material they were not tuned on
# (the second table below); not among the 28 of the front.
#
# | name | Debian package (bookworm) | file | what |
# |---|---|---|---|
# | dog_1080p | forensics-samples-files 1.1.4-5 | original-files/movie1/VID_20191220_170832.mp4 (H.264, 1920x1080, 29.97, 41 frames) | phone video of a dog lying in a hall, hand-held |
# | cockatoo_720p | python3-imageio 2.4.1-5 | imageio/resources/images/cockatoo.mp4 (H.264, 1280x720, 20 fps) | cockatoo walking up to a hand-held camera, window behind |
# | diver_vga | pd-extendedview 0.5~repack-4 | media/diver.mov (MJPEG, 640x480, 25 fps) | under water, hand-held, bubbles and a diver |
# | poster_384 | visp-images-data 3.5.0-1 | ViSP-images/video/cube.mpeg (MPEG-1, 384x288, 25 fps) | camera moving over a printed poster and a target (visual servoing) |
# | plant_qvga | python3-imageio 2.4.1-5 | imageio/resources/images/realshort.mp4 (H.264, 320x240, 36 frames) | hand-held pan over a desk and a plant, bright window |
# | lego_560 | python3-hug-doc 2.6.0-2.4 | examples/streaming_movie_server/movie.mp4 (H.264, 560x320, 30 fps) | a Lego model under a lamp |
# | coin_568 | node-opencv 7.0.0+git20200316 | examples/files/motion.mov (H.264, 568x320, 30 fps) | a coin on a plain wall, fixed camera, a pen entering |
# | ball_576 | python3-mecavideo 8.0~rc5-1 | pymecavideo/data/video/balle-jbart.mp4 (H.264, 720x576, 25 fps) | a ball thrown in a classroom, fixed camera |
# Licences: see each package's copyright file. All were lossy-compressed at
# the source.
#
# SET=kinds:
#
# | name | Debian package (bookworm) | file | what |
# |---|---|---|---|
# | birds_720p | wordpress-theme-twentytwentytwo 6.1.9+dfsg1-0+deb12u1 | assets/videos/birds.mp4 (H.264, 1280x720, 30 fps, 31 frames) | 2D animation: birds flying over a floral pattern |
# | calais_214 | python-nbsphinx-doc 0.8.11+ds-1 | html/www/wikimediacommons/Shepard_Calais_1906_FrenchGP.ogv (Theora, 218x160 as ffmpeg decodes it, 15 fps) | film of 1906: grain, flicker, a moving camera |
# | album_160 | kphotoalbum 5.9.1-1 | demo/movie.avi (MJPEG, 160x120, 15 fps) | webcam, a face in a room |
# | anim_256 | gem-doc 1:0.94-8 | examples/data/anim-1.mov (MJPEG, 256x256, 30 fps) | rendered 3D animation: a teapot, a plane |
# | screen_720p | forensics-samples-files 1.1.4-5 | original-files/movie2/movie-hello.mp4 (H.264, 1280x720, 30 fps, 250 frames) | a screen recording: a terminal typed into, a webcam's picture of the typist inset |
set -euo pipefail
DIR=${1:?usage: real.sh DIR [N]}
N=${2:-90}
mkdir -p "$DIR"
DIR=$(cd "$DIR" && pwd)
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT

have() { [ -s "$DIR/$1.y4m" ]; }

# unpack PACKAGE: the package's files under $W/PACKAGE.
unpack() {
  [ -d "$W/$1" ] && return 0
  (cd "$W" && (apt-get download "$1" >/dev/null 2>&1 || { apt-get update >/dev/null && apt-get download "$1" >/dev/null; }))
  mkdir -p "$W/$1"
  dpkg-deb -x "$W/$1"_*.deb "$W/$1"
  echo "$1: $(dpkg-deb -f "$W/$1"_*.deb Version)"
}

# clip NAME PACKAGE PATH: the first N frames of PATH (inside PACKAGE) as NAME.y4m.
clip() {
  have "$1" && return 0
  unpack "$2"
  ffmpeg -hide_banner -loglevel error -nostdin -y -threads 1 -i "$W/$2/$3" -map 0:v:0 \
    -frames:v "$N" -pix_fmt yuv420p -strict -1 "$DIR/$1.y4m"
  echo "$1: $(head -c 80 "$DIR/$1.y4m" | head -1)"
}

if [ "${SET:-cameras}" = kinds ]; then
  clip birds_720p wordpress-theme-twentytwentytwo usr/share/wordpress/wp-content/themes/twentytwentytwo/assets/videos/birds.mp4
  clip calais_214 python-nbsphinx-doc usr/share/doc/python-nbsphinx/html/www/wikimediacommons/Shepard_Calais_1906_FrenchGP.ogv
  clip album_160 kphotoalbum usr/share/kphotoalbum/demo/movie.avi
  clip anim_256 gem-doc usr/share/gem/examples/data/anim-1.mov
  clip screen_720p forensics-samples-files usr/share/forensics-samples/original-files/movie2/movie-hello.mp4
  exit 0
fi

clip dog_1080p forensics-samples-files usr/share/forensics-samples/original-files/movie1/VID_20191220_170832.mp4
clip cockatoo_720p python3-imageio usr/lib/python3/dist-packages/imageio/resources/images/cockatoo.mp4
clip plant_qvga python3-imageio usr/lib/python3/dist-packages/imageio/resources/images/realshort.mp4
clip diver_vga pd-extendedview usr/share/doc/pd-extendedview/media/diver.mov
clip poster_384 visp-images-data usr/share/visp-images-data/ViSP-images/video/cube.mpeg
clip lego_560 python3-hug-doc usr/share/doc/python3-hug/examples/streaming_movie_server/movie.mp4
clip coin_568 node-opencv usr/share/doc/node-opencv/examples/files/motion.mov
clip ball_576 python3-mecavideo usr/share/pymecavideo/data/video/balle-jbart.mp4
