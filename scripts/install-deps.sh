#!/usr/bin/env bash
# Installs the Debian packages ssdo needs, only those that are missing.
# Safe to run again; uses sudo when not root.
set -euo pipefail

PACKAGES=(
  cmake g++ make pkg-config
  libopenimageio-dev openimageio-tools libopenexr-dev libimath-dev libdeflate-dev libisal-dev libpng-dev
  libopencv-core-dev libglm-dev libhwy-dev nlohmann-json3-dev libcli11-dev
  libgtest-dev libgmock-dev libbenchmark-dev fonts-dejavu-core
  clang libclang-rt-dev universal-ctags
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "ssdo: all build dependencies are installed."
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then SUDO="sudo"; else
    echo "ssdo: missing packages (${missing[*]}) and not root; install them as root." >&2
    exit 1
  fi
fi
echo "ssdo: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
