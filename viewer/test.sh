#!/usr/bin/env bash
# The viewer page in headless Chromium (run by .ci/run): installs Chromium
# (Debian's package) and the page's packages when missing, exports a
# tanker1 tileset and a ship 10^5 one, serves each, and checks the page
# draws it (the ship's far tiles by their group bounds, not boxes).
# usage: viewer/test.sh MKTREE_BINARY [SCREENSHOT.png]
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
mktree="$(realpath "$1")"
shot="$(realpath -m "${2:-$here/../target/viewer-tanker1.png}")"
if ! command -v chromium >/dev/null; then
  echo "installing Debian's chromium for the page test"
  sudo=""; [ "$(id -u)" = 0 ] || sudo="sudo"
  $sudo apt-get update -qq && $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null
fi
[ -d "$here/node_modules/playwright-core" ] || bash "$here/install.sh"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
"$mktree" gen tanker1 -o "$work/tanker1.obj" >/dev/null 2>&1
"$mktree" build "$work/tanker1.obj" -o "$work/tanker1.mkt" >/dev/null
"$mktree" export-3dtiles "$work/tanker1.mkt" "$work/tiles"
mkdir -p "$(dirname "$shot")"
node "$here/test.mjs" "$mktree" "$work/tiles" "$shot"
# Ship scale: 100,000 objects, 18,437 tiles; the first view sees it whole,
# so the page draws internal tiles, which must show group bounds.
"$mktree" gen ship --objects 100000 -o "$work/ship.obj" >/dev/null 2>&1
"$mktree" build "$work/ship.obj" -o "$work/ship.mkt" >/dev/null
rm -rf "$work/tiles" "$work/ship.obj"
"$mktree" export-3dtiles "$work/ship.mkt" "$work/tiles" >/dev/null
node "$here/test.mjs" "$mktree" "$work/tiles" "${shot%.png}-ship.png" 0.02 5
