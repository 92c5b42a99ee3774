#!/bin/bash
# A run's report.html as a real browser shows it: a headless Chromium screenshot of
# DIR/report.html, written to DIR/report.png (the whole page down to HEIGHT pixels).
#
#   bash scripts/report_screenshot.sh out/encircling_buckle [WIDTH [HEIGHT]]
#
# Installs Debian's chromium with apt-get when it is missing (as root, or with sudo). The page
# needs no network and no script: the pictures are inside it (eyeball_fenicsx/output/report.py).
# Chromium's --screenshot takes the window as it is, so HEIGHT (default 4200) should hold the
# page; WIDTH defaults to 1400, the page's width.
set -euo pipefail

dir=${1:?usage: bash scripts/report_screenshot.sh DIR [WIDTH [HEIGHT]]}
width=${2:-1400}
height=${3:-4200}
page=$(realpath "$dir/report.html")
[ -f "$page" ] || { echo "error: no report.html in $dir" >&2; exit 2; }

if ! command -v chromium >/dev/null; then
    sudo=""
    [ "$(id -u)" -eq 0 ] || sudo=sudo
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq chromium >/dev/null
fi

shot=$(realpath "$dir")/report.png
# --no-sandbox: Chromium's sandbox refuses to run as root; the page is our own file.
chromium --headless --no-sandbox --disable-gpu --hide-scrollbars --allow-file-access-from-files \
    --window-size="$width,$height" --screenshot="$shot" "file://$page" 2>/dev/null
[ -s "$shot" ] || { echo "error: chromium wrote no screenshot" >&2; exit 1; }
echo "$shot"
