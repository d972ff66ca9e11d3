#!/usr/bin/env bash
# Installs every build, test and figure dependency of vibroimpact from Debian's packages.
# Idempotent: installs only what is missing and prints nothing when all is present.
# Runs as root on a fresh Debian 12 machine (or with sudo when available).
set -euo pipefail

packages=(
  build-essential cmake pkg-config
  libeigen3-dev libyaml-cpp-dev libhdf5-dev catch2 libcli11-dev libfmt-dev
  python3-numpy python3-matplotlib python3-h5py
  pybind11-dev python3-dev python3-pytest   # the Python module `vibro` (framework/python) and its tests
  libsundials-dev                     # benchmark peer only: ARKODE and CVODE in tools/bench/work_precision
  libboost-dev                        # benchmark peer only: Boost.Odeint in tools/bench/bench_taylor_odeint
  openmpi-bin libopenmpi-dev          # optional MPI sweeps (found at configure time) and their test
  liblapack-dev                       # LAPACK dstemr: O(N²) modal set-up of long chains (framework/src/modal.cpp)
  clang libclang-rt-14-dev libomp-dev # the sanitize preset (ASan + UBSan) and the libFuzzer targets (docs/fuzzing.md)
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
[ ${#missing[@]} -eq 0 ] && exit 0

sudo=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then sudo="sudo"; else
    echo "bootstrap: need root to install: ${missing[*]}" >&2; exit 1
  fi
fi
echo "bootstrap: installing ${missing[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq >/dev/null
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
