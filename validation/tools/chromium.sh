# Sourced by the headless-Chromium checks (check_report.sh, check_view.sh): apt_install and
# need_chromium, which sets CHROMIUM to the system's Chromium, installing it with apt-get when
# it is not there (CI calls the checks on a clean machine). The caller names itself in
# CHECK_NAME for the messages.

SUDO=""
if [ "$(id -u)" != 0 ] && command -v sudo >/dev/null 2>&1; then SUDO=sudo; fi
apt_updated=""
apt_install() {
  if [ -z "$apt_updated" ]; then $SUDO apt-get update -qq >&2; apt_updated=1; fi
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "$@" >&2
}

find_chromium() {
  for c in chromium chromium-browser google-chrome google-chrome-stable; do
    if command -v "$c" >/dev/null 2>&1; then
      command -v "$c"
      return 0
    fi
  done
  return 1
}

need_chromium() {
  if ! CHROMIUM=$(find_chromium); then
    echo "$CHECK_NAME: installing chromium (apt-get)" >&2
    apt_install chromium
    CHROMIUM=$(find_chromium) || { echo "$CHECK_NAME: chromium could not be installed" >&2; exit 2; }
  fi
}
