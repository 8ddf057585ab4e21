#!/usr/bin/env bash
# The accuracy study in one command: builds, runs every sweep of `mpm study` (about a quarter
# of an hour on 2 cores), writes docs/accuracy/study.csv and series.csv, and draws the figures
# of docs/accuracy.md into docs/images/. Extra arguments go to `mpm study` (e.g. --quick).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/build.sh
if ! /usr/bin/python3 -c "import matplotlib" 2>/dev/null; then
  sudo_cmd=""
  [ "$(id -u)" -ne 0 ] && sudo_cmd="sudo"
  $sudo_cmd apt-get update -qq && $sudo_cmd apt-get install -y -qq python3-matplotlib
fi
build/bin/mpm study -o docs/accuracy "$@"
/usr/bin/python3 scripts/plot_study.py docs/accuracy -o docs/images
