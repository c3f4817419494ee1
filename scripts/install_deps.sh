#!/usr/bin/env bash
# Installs Streetlight's build and test dependencies from Debian 12 packages. Idempotent: it
# only calls apt-get when a package is missing. Usage: scripts/install_deps.sh [--anchors] [--mpi] [--clang]
#   --anchors  also install the comparison anchors (python3-torch with OpenBLAS, jemalloc for it
#              (scripts/anchor_allocator.py), libembree-dev)
#   --mpi      also install Open MPI (data-parallel training, docs/DISTRIBUTED.md)
#   --clang    also install clang 14 and its sanitizer and libFuzzer runtimes (scripts/fuzz.sh)
set -euo pipefail

packages=(cmake g++ make ccache pkg-config
          libeigen3-dev libopenimageio-dev libopenexr-dev libtinygltf-dev libstb-dev
          libglm-dev nlohmann-json3-dev libgtest-dev
          pybind11-dev python3-dev python3-numpy python3-pytest)
for arg in "$@"; do
  case "$arg" in
    # OpenBLAS: without it (--no-install-recommends) PyTorch multiplies with the reference BLAS,
    # 15x slower (1024^3: 374 against 21-27 ms on an AMD EPYC, 2026-11-27).
    --anchors) packages+=(python3-torch libopenblas0-pthread libjemalloc2 libembree-dev) ;;
    --mpi) packages+=(libopenmpi-dev openmpi-bin) ;;
    --clang) packages+=(clang libclang-rt-14-dev) ;;
    -h|--help) sed -n '2,7p' "$0"; exit 0 ;;
    *) echo "error: unknown option '$arg' (try --help)" >&2; exit 2 ;;
  esac
done

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#packages[@]} packages present" >&2
  exit 0
fi
echo "install_deps: installing ${missing[*]}" >&2
sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then sudo_cmd=(sudo); fi
export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -qq
"${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
