#!/usr/bin/env bash
# Pictures and a movie of a DEM run: PNG frames and an MP4 of the particles (spheres coloured by
# speed), the tools, the walls and the time, the camera framing the tools over the run.
#   bash scripts/render.sh RUN.xdmf [--out DIR] [--every N] [--width W] [--fps F] [--no-movie] [--last]
# RUN.xdmf is what dem_run or dem_service writes beside its HDF5 file. Uses Debian's ParaView
# (python3-paraview: pvbatch) under xvfb-run, and ffmpeg for the MP4 (docs/visualise.md).
set -euo pipefail
usage() {
  cat <<'EOF'
usage: scripts/render.sh RUN.xdmf [options]
  --out DIR     where the frames and the movie go (default: RUN_render/ beside RUN.xdmf)
  --every N     every N-th snapshot (and always the last one); default 1
  --width W     picture width in pixels (even, 64..7680); the height is 9/16 of it; default 1280
  --fps F       frames per second of the movie (1..120); default 10
  --no-movie    PNG frames only
  --last        only the last snapshot: DIR/STEM_last.png, no movie
Writes DIR/STEM_00000.png ... and DIR/STEM.mp4 (STEM: the file name without .xdmf).
EOF
}
die() { echo "render: $*" >&2; exit 2; }

xdmf="" out="" every=1 width=1280 fps=10 movie=1 last=0
while [ $# -gt 0 ]; do
  case "$1" in
    -h|--help) usage; exit 0 ;;
    --out) [ $# -ge 2 ] || die "--out needs a folder"; out="$2"; shift 2 ;;
    --every) [ $# -ge 2 ] || die "--every needs a number"; every="$2"; shift 2 ;;
    --width) [ $# -ge 2 ] || die "--width needs a number of pixels"; width="$2"; shift 2 ;;
    --fps) [ $# -ge 2 ] || die "--fps needs a number"; fps="$2"; shift 2 ;;
    --no-movie) movie=0; shift ;;
    --last) last=1; movie=0; shift ;;
    -*) usage >&2; die "unknown option '$1'" ;;
    *) [ -z "$xdmf" ] || die "one XDMF file only (got '$xdmf' and '$1')"; xdmf="$1"; shift ;;
  esac
done
[ -n "$xdmf" ] || { usage >&2; die "no XDMF file given"; }
[[ "$every" =~ ^[0-9]+$ ]] && [ "$every" -ge 1 ] || die "--every '$every': expected a whole number >= 1"
[[ "$width" =~ ^[0-9]+$ ]] && [ "$width" -ge 64 ] && [ "$width" -le 7680 ] && [ $((width % 2)) -eq 0 ] ||
  die "--width '$width': expected an even number of pixels from 64 to 7680 (the MP4 needs even sizes)"
[[ "$fps" =~ ^[0-9]+$ ]] && [ "$fps" -ge 1 ] && [ "$fps" -le 120 ] || die "--fps '$fps': expected a whole number from 1 to 120"
height=$(( (width * 9 / 16 + 1) / 2 * 2 ))

[ -e "$xdmf" ] || die "$xdmf: no such file (dem_run and dem_service write FILE.xdmf beside their output FILE.h5)"
[ -f "$xdmf" ] || die "$xdmf: not a file"
head -c 4096 "$xdmf" | grep -q "<Xdmf" ||
  die "$xdmf: not an XDMF file (no <Xdmf> element); give the .xdmf beside a dem_run/dem_service output, not the .h5"
# The Xdmf3 reader resolves the HDF5 file against the XDMF's folder only when given a full path.
xdmf=$(realpath "$xdmf")
stem=$(basename "$xdmf"); stem="${stem%.*}"
[ -n "$out" ] || out="$(dirname "$xdmf")/${stem}_render"
mkdir -p "$out" || die "cannot create the folder '$out'"
out=$(realpath "$out")

command -v pvbatch >/dev/null ||
  die "pvbatch not found: install Debian's ParaView with 'apt-get install python3-paraview' (bash scripts/setup.sh does)"
command -v xvfb-run >/dev/null ||
  die "xvfb-run not found: install 'apt-get install xvfb xauth' (bash scripts/setup.sh does); ParaView draws into a virtual screen"
if [ "$movie" = 1 ] && ! command -v ffmpeg >/dev/null; then
  die "ffmpeg not found: install it with 'apt-get install ffmpeg' (bash scripts/setup.sh does), or pass --no-movie"
fi

here=$(cd "$(dirname "$0")" && pwd)
# Old frames of this stem would end up in the movie.
[ "$last" = 1 ] || rm -f "$out/${stem}"_[0-9][0-9][0-9][0-9][0-9].png
log=$(mktemp)
trap 'rm -f "$log" "$log.x"' EXIT
render() {
  xvfb-run -a -e "$log.x" -s "-screen 0 $((width + 64))x$((height + 64))x24" \
    pvbatch "$here/render.py" "$xdmf" "$out" "$stem" "$every" "$width" "$height" "$last" >"$log" 2>&1
}
# Up to three more tries, a few seconds apart, when the virtual screen was not there (xvfb-run
# picks a free display number, and another X server starting at the same moment can take it;
# on a loaded host the server has also failed twice in a row).
render_retrying() {
  local try
  render && return 0
  for try in 1 2 3; do
    grep -q "bad X server connection" "$log" || return 1
    echo "render: the virtual X screen failed, trying again in $((2 * try)) s ($try of 3)" >&2
    sleep $((2 * try))
    render && return 0
  done
  return 1
}
if ! render_retrying; then
  # render.py's own refusals (a file it cannot use) are the whole story.
  if grep -q "^render: " "$log"; then grep "^render: " "$log" >&2; exit 2; fi
  grep -v -E "^\s*[0-9]+\s+0x|^\(" "$log" | tail -20 >&2
  cat "$log.x" >&2
  die "ParaView could not render $xdmf (messages above)"
fi
grep -E "^frame " "$log" || true
frames=$(sed -n 's/^frames: //p' "$log")
[ -n "$frames" ] || { tail -20 "$log" >&2; die "ParaView did not report its frames (messages above)"; }
if [ "$last" = 1 ]; then
  echo "render: wrote $out/${stem}_last.png"
  exit 0
fi
echo "render: wrote $frames frame(s) $out/${stem}_NNNNN.png"
if [ "$movie" = 1 ]; then
  ffmpeg -loglevel error -y -framerate "$fps" -i "$out/${stem}_%05d.png" \
    -c:v libx264 -pix_fmt yuv420p -crf 20 "$out/${stem}.mp4" ||
    die "ffmpeg could not write $out/${stem}.mp4"
  echo "render: wrote $out/${stem}.mp4 ($frames frames at $fps per second)"
fi
