#!/usr/bin/env bash
# Installs the Debian packages stf needs that are not installed yet. Needs root only when
# something is missing; then it runs apt-get itself if root, else through sudo.
set -euo pipefail
pkgs=(cmake make gcc pkg-config libode-dev libccd-dev libhdf5-dev libfyaml-dev libpng-dev
      hdf5-tools python3 python3-h5py python3-numpy python3-pil
      openmpi-bin libopenmpi-dev)  # optional for the build: `mpirun stf sweep` (12.5 MB)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
echo "installing: ${missing[*]}" >&2
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo > /dev/null || { echo "install-deps: run as root (or install sudo)" >&2; exit 1; }
  exec sudo "$0" "$@"
fi
export DEBIAN_FRONTEND=noninteractive
apt-get install -y --no-install-recommends "${missing[@]}" ||
  { apt-get update && apt-get install -y --no-install-recommends "${missing[@]}"; }
