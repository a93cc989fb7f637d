# Sourced by the tools. install_missing WHO PACKAGE... (setup.sh only) installs with
# apt-get the Debian packages that are not installed yet (as root, or through sudo); WHO
# names the script in its messages. Nothing happens when all are there.
# require_installed WHO COMMAND PACKAGE... (the scripts the tests run, which install
# nothing) exits with status 2 and names COMMAND, the one that installs them, when a
# package is missing.
install_missing() {
  local who=$1 p sudo=""
  shift
  local missing=()
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  echo "$who: installing ${missing[*]}"
  if [ "$(id -u)" != 0 ]; then
    command -v sudo >/dev/null || { echo "$who: need root (or sudo) to install: ${missing[*]}" >&2; exit 1; }
    sudo=sudo
  fi
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -qq
  $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
}

require_installed() {
  local who=$1 command=$2 p
  shift 2
  local missing=()
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  echo "$who: missing Debian packages: ${missing[*]}" >&2
  echo "  Install them with:  $command" >&2
  exit 2
}
