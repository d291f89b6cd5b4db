# Sourced by scripts/test and scripts/run: installs what rovernav needs on a fresh
# Debian 12 machine, and nothing when it is already there.
#   * Debian packages (apt-get, as root; otherwise prints the command to run)
#   * a virtual environment in .venv with the host package and its test tools
# Set ROVERNAV_NO_APT=1 to skip the Debian check (e.g. on another distribution).

ROVERNAV_APT_PACKAGES=(
  cmake g++ make                                            # native build of the firmware core
  gcc-avr avr-libc binutils-avr arduino-core-avr            # the Uno image without PlatformIO
  doctest-dev                                               # native unit tests
  clang libclang-rt-14-dev                                  # libFuzzer
  simavr libsimavr-dev libelf-dev pkg-config                # the Uno image in an AVR simulator
)

rovernav_log() { printf '\033[1m[rovernav]\033[0m %s\n' "$*" >&2; }

rovernav_ensure_apt() {
  [ "${ROVERNAV_NO_APT:-0}" = 1 ] && return 0
  command -v dpkg-query >/dev/null 2>&1 || { rovernav_log "not a Debian system: skipping package check (set ROVERNAV_NO_APT=1 to silence)"; return 0; }
  local missing=()
  for pkg in "${ROVERNAV_APT_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  local sudo=""
  if [ "$(id -u)" != 0 ]; then
    if command -v sudo >/dev/null 2>&1; then sudo="sudo"; else
      rovernav_log "missing Debian packages: ${missing[*]}"
      rovernav_log "run as root: apt-get update && apt-get install -y --no-install-recommends ${missing[*]}"
      return 1
    fi
  fi
  rovernav_log "installing Debian packages: ${missing[*]}"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
}

rovernav_ensure_venv() {
  local py=${PYTHON:-python3}
  if [ ! -x .venv/bin/python ]; then
    rovernav_log "creating .venv"
    "$py" -m venv .venv
  fi
  # Reinstall when pyproject.toml changes (the stamp holds its hash).
  local want have
  want=$(sha256sum pyproject.toml | cut -d' ' -f1)
  have=$(cat .venv/.rovernav-stamp 2>/dev/null || true)
  if [ "$want" != "$have" ]; then
    rovernav_log "installing the rovernav package and its test tools into .venv"
    .venv/bin/python -m pip install -q --upgrade pip >/dev/null 2>&1 || true
    .venv/bin/python -m pip install -q -e '.[test]'
    echo "$want" > .venv/.rovernav-stamp
  fi
}
