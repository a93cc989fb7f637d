#!/usr/bin/env bash
# Renders a run's output directory to PNG frames (and an MP4) with ParaView's pvpython,
# off screen. Installs ParaView, Xvfb and ffmpeg with apt-get when they are missing and
# this runs as root (or with sudo); tools/setup.sh does not install them (they are large).
#
# Usage: bash tools/render.sh OUTPUT_DIR [--frames all|last|N,M,A:B] [--color object|material|
#          contact_force|velocity|penetration|owner_rank] [--out DIR] [--size WxH]
#          [--view iso|front|side|top|low|back] [--zoom Z] [--fit run|frames] [--animation] ...
#        bash tools/render.sh --help          (all options; docs/output-format.md)
# Environment: SOFTCONTACT_NO_INSTALL=1 reports missing packages instead of installing them;
#              SOFTCONTACT_RENDER_MODE=offscreen|display|xvfb skips the detection.
set -uo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
script="$root/tools/render.py"
me="render"

usage() { sed -n '5,8p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//' >&2; }

# The output directory (first argument that is not an option) and whether an animation is asked for.
dir="" animation=0 help=0
for a in "$@"; do
  case "$a" in
    -h|--help) help=1 ;;
    --animation) animation=1 ;;
  esac
done
if [ "$help" = 0 ]; then
  if [ $# -eq 0 ] || [[ "$1" == -* ]]; then
    echo "$me: no output directory given" >&2; usage; exit 2
  fi
  dir=$1
  if [ ! -d "$dir" ]; then
    echo "$me: output directory '$dir' does not exist (run a scene first, e.g. bash tools/run.sh)" >&2; exit 2
  fi
  if [ ! -f "$dir/frames.xdmf" ]; then
    echo "$me: '$dir/frames.xdmf' is missing: not a softcontact output directory, or its run wrote no frame yet" >&2
    exit 2
  fi
fi

# Packages: pvpython, h5py (object names, kinematic objects, colour ranges), an X server
# for the Debian ParaView build (it has no EGL/OSMesa off-screen support), ffmpeg for --animation.
packages=(paraview python3-paraview python3-h5py xvfb)
[ "$animation" = 1 ] && packages+=(ffmpeg)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ! command -v dpkg-query >/dev/null; then  # not Debian: look for the programs themselves
  missing=()
  command -v pvpython >/dev/null || missing+=(paraview)
fi
if [ ${#missing[@]} -gt 0 ]; then
  sudo=""
  if [ "${SOFTCONTACT_NO_INSTALL:-0}" = 1 ]; then
    cannot="SOFTCONTACT_NO_INSTALL=1 is set"
  elif [ "$(id -u)" != 0 ] && ! command -v sudo >/dev/null; then
    cannot="this is not root and there is no sudo"
  else
    cannot=""
    [ "$(id -u)" != 0 ] && sudo=sudo
  fi
  if [ -n "$cannot" ] || ! command -v apt-get >/dev/null; then
    echo "$me: missing ${missing[*]}; ${cannot:-apt-get is not available}. Install them with:" >&2
    echo "  apt-get install paraview python3-paraview python3-h5py xvfb ffmpeg" >&2
    exit 2
  fi
  echo "$me: installing ${missing[*]} (ParaView is large: a few minutes)"
  export DEBIAN_FRONTEND=noninteractive
  if ! { $sudo apt-get update -qq && $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null; }; then
    echo "$me: could not install ${missing[*]}; install them with: apt-get install ${missing[*]}" >&2
    exit 2
  fi
fi
if ! command -v pvpython >/dev/null; then
  echo "$me: pvpython is not on PATH although paraview is installed; install it with: apt-get install paraview python3-paraview" >&2
  exit 2
fi

work=$(mktemp -d "${TMPDIR:-/tmp}/softcontact-render.XXXXXX")
xpid=""
cleanup() { [ -n "$xpid" ] && kill "$xpid" 2>/dev/null; rm -rf "$work"; }
trap cleanup EXIT
trap 'exit 130' INT TERM

# pvpython prints a long stack trace when it cannot open a window: keep the lines that say why.
filter() { grep --line-buffered -vE '^[[:space:]]*[0-9]+[[:space:]]+0x|Stack trace:|Loguru caught|^.\[0m.?$' ; }

# The way to draw without a screen: ParaView's own off-screen mode where its build has one,
# else the display we have, else a private Xvfb server.
probe() {  # probe CMD...: can this pvpython draw an image this way?
  printf 'from paraview.simple import *\nShow(Sphere())\nv = GetActiveViewOrCreate("RenderView")\nSaveScreenshot(r"%s/probe.png", v, ImageResolution=[32, 32])\n' \
    "$work" > "$work/probe.py"
  rm -f "$work/probe.png"
  (timeout 120 "$@" "$work/probe.py" >"$work/probe.log" 2>&1) 2>/dev/null && [ -s "$work/probe.png" ]
}
start_xvfb() {
  command -v Xvfb >/dev/null || { echo "$me: Xvfb is missing; install it with: apt-get install xvfb" >&2; exit 2; }
  # -displayfd: Xvfb picks a free display and writes its number once it accepts clients.
  # -noreset: by default an X server resets when its last client leaves and drops the
  # connections that arrive meanwhile; pvpython connects, leaves and connects again.
  # (xvfb-run -a has that race: about one run in four aborted with "bad X server connection".)
  Xvfb -displayfd 3 -screen 0 1920x1080x24 -nolisten tcp -noreset 3>"$work/display" 2>"$work/xvfb.log" &
  xpid=$!
  for _ in $(seq 200); do [ -s "$work/display" ] && break; kill -0 "$xpid" 2>/dev/null || break; sleep 0.05; done
  [ -s "$work/display" ] || { echo "$me: Xvfb did not start:" >&2; cat "$work/xvfb.log" >&2; exit 1; }
  DISPLAY=":$(head -1 "$work/display")"
  export DISPLAY
}

# Whether this ParaView build renders off screen is remembered per pvpython binary
# (the probe takes seconds).
cache="${XDG_CACHE_HOME:-${HOME:-/tmp}/.cache}/softcontact/render-offscreen"
pv_id=$(stat -L -c '%n %s %Y' "$(command -v pvpython)" 2>/dev/null)
mode=${SOFTCONTACT_RENDER_MODE:-}
[ "$help" = 1 ] && mode=display  # --help draws nothing
if [ -z "$mode" ]; then
  offscreen=$(grep -sxF -A1 "$pv_id" "$cache" | tail -1)
  if [ -z "$offscreen" ] || [ "$offscreen" = "$pv_id" ]; then
    offscreen=no
    probe pvpython --force-offscreen-rendering 2>/dev/null && offscreen=yes
    { mkdir -p "$(dirname "$cache")" && printf '%s\n%s\n' "$pv_id" "$offscreen" > "$cache"; } 2>/dev/null
  fi
  if [ "$offscreen" = yes ]; then mode=offscreen
  elif [ -n "${DISPLAY:-}" ] && probe pvpython 2>/dev/null; then mode=display
  else mode=xvfb
  fi
fi
case "$mode" in
  offscreen) cmd=(pvpython --force-offscreen-rendering) ;;
  display) cmd=(pvpython) ;;
  xvfb) start_xvfb; cmd=(pvpython) ;;
  *) echo "$me: SOFTCONTACT_RENDER_MODE must be offscreen, display or xvfb, got '$mode'" >&2; exit 2 ;;
esac

# A connection to an X server that is resetting fails ("bad X server connection"; a
# shared display without -noreset): try again, up to five times.
for attempt in 1 2 3 4 5; do
  { "${cmd[@]}" "$script" "$@" 2>&1 | tee "$work/log" | filter; rc=${PIPESTATUS[0]}; } 2>/dev/null
  if [ "$rc" != 0 ] && [ "$mode" != offscreen ] && grep -q "bad X server connection" "$work/log"; then
    echo "$me: could not connect to the X server $DISPLAY (attempt $attempt); trying again" >&2
    continue
  fi
  break
done
exit "$rc"
