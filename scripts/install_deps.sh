#!/usr/bin/env bash
# Installs the Debian packages horizonreg needs, skipping those present.
# Usage: install_deps.sh [--test | --fuzz]   (--test adds what only the tests
# need, --fuzz clang and libFuzzer for `make fuzz`)
set -euo pipefail
packages=(
  build-essential cmake pkg-config file python3 bc
  libgdal-dev gdal-bin libopencv-dev libeigen3-dev libceres-dev libgeographiclib-dev
  libcli11-dev nlohmann-json3-dev libexiv2-dev liblensfun-dev liblensfun-data-v1 libgtest-dev libgmock-dev libbenchmark-dev
  python-matplotlib-data   # the demo's DEM: jacksboro_fault_dem.npz
  pybind11-dev python3-dev python3-numpy   # the Python module
)
if [ "${1:-}" = "--test" ]; then
  packages+=(grass-core)  # the r.horizon comparison test
  packages+=(python3-pytest python3-distributed)  # the Python API and Dask tests
  packages+=(python3-opencv)  # eval_real.py's thin-sky crops
fi
if [ "${1:-}" = "--fuzz" ]; then
  packages+=(clang libclang-rt-dev)  # libFuzzer (-fsanitize=fuzzer) comes with clang's compiler-rt
fi
missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then missing+=("$p"); fi
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi
echo "Installing: ${missing[*]}"
sudo=""
if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
