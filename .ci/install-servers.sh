#!/usr/bin/env bash
# Installs the servers the object-store tests (tests/remote_*.rs) start on
# 127.0.0.1: Debian's nginx for plain HTTP range requests, and moto's S3
# server (PyPI `moto[server]`, in target/server-venv) for the S3 protocol.
# Prints the environment the tests read, for `eval`.
set -euo pipefail
cd "$(dirname "$0")/.."
sudo=""
[ "$(id -u)" = 0 ] || sudo="sudo"
if ! command -v nginx >/dev/null && [ ! -x /usr/sbin/nginx ]; then
  echo "installing Debian's nginx for the object-store tests" >&2
  $sudo apt-get update -qq >&2 && $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq nginx >&2
fi
if [ ! -x target/server-venv/bin/moto_server ]; then
  echo "installing moto's S3 server into target/server-venv" >&2
  python3 -m venv target/server-venv
  target/server-venv/bin/pip install --quiet 'moto[server]==5.*' >&2
fi
echo "export MKTREE_MOTO_SERVER=$PWD/target/server-venv/bin/moto_server"
echo "export MKTREE_REMOTE_TESTS=required"
