#!/usr/bin/env bash
# Installs the viewer page's packages (three, 3d-tiles-renderer) and its
# test's driver (playwright-core) into viewer/node_modules, at the versions
# package-lock.json pins. `mktree serve` serves them from there.
set -euo pipefail
cd "$(dirname "$0")"
command -v npm >/dev/null || { echo "viewer/install.sh: npm is not installed" >&2; exit 1; }
npm ci --legacy-peer-deps --no-audit --no-fund --loglevel=error
