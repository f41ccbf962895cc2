#!/usr/bin/env bash
# usage: fetch_scans.sh [DEST]   (DEST: data/real/scans)
# The scanned models of `source=scans` (nbv/assets/real_objects.py): Debian's libcgal-demo
# 5.5.1-2 holds them in its documentation's data.tar.gz. The package is downloaded, not installed
# (it depends on libcgal-dev and recommends Qt), and only the listed OFF files are kept, each
# checked against its SHA-256 in nbv/assets/scans.sha256. Quiet when they are all there already.
set -euo pipefail

dest="${1:-data/real/scans}"
package="libcgal-demo=5.5.1-2"
manifest="$(cd "$(dirname "$0")/.." && pwd)/nbv/assets/scans.sha256"

if [ -d "$dest" ] && (cd "$dest" && sha256sum --quiet --check "$manifest" >/dev/null 2>&1); then
  exit 0
fi
for tool in apt-get dpkg-deb sha256sum tar; do
  if ! command -v "$tool" >/dev/null 2>&1; then
    echo "fetch_scans: $tool is missing; the scans come from Debian's $package" >&2
    exit 1
  fi
done

work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
echo "fetch_scans: downloading $package (24 MB) for its scanned models" >&2
if ! (cd "$work" && apt-get download -qq "$package" 2>/dev/null); then
  if [ "$(id -u)" -eq 0 ]; then
    apt-get update -qq
    (cd "$work" && apt-get download -qq "$package" 2>/dev/null)
  else
    echo "fetch_scans: apt-get download $package failed; run 'sudo apt-get update' and retry" >&2
    exit 1
  fi
fi
dpkg-deb -x "$work"/libcgal-demo_*.deb "$work/deb"
mapfile -t files < <(awk '{print "data/meshes/" $2}' "$manifest")
tar -xzf "$work/deb/usr/share/doc/libcgal-demo/data.tar.gz" -C "$work" "${files[@]}"
if ! (cd "$work/data/meshes" && sha256sum --quiet --check "$manifest"); then
  echo "fetch_scans: the files of $package differ from $manifest; nothing was copied" >&2
  exit 1
fi
mkdir -p "$dest"
cp "$work"/data/meshes/* "$dest"/
echo "fetch_scans: $(wc -l <"$manifest") scans in $dest" >&2
