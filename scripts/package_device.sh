#!/usr/bin/env bash
# Packs what the GPU machine needs to run fmg-cuda's tests and benchmarks into .device/bundle.tar.xz (git-ignored):
# the CLI and the CUDA-related test programs built here in build/ (configure with CUDA found: nvcc 13, sm_90), and
# every shared library they load except the C runtime, which that machine has. scripts/device_check.sh unpacks and
# runs it there. Usage: scripts/package_device.sh  (after scripts/setup.sh)
set -euo pipefail
cd "$(dirname "$0")/.."
grep -q "^MGCLOTH_CUDA_BUILT:INTERNAL=ON" build/CMakeCache.txt 2>/dev/null ||
  { echo "package_device: build/ has no CUDA backend (is nvcc installed? see MGCLOTH_CUDA in CMakeLists.txt)" >&2; exit 1; }
cmake --build build -j "$(nproc)" --target mgcloth_cli mgcloth_tests_cuda mgcloth_tests_solvers mgcloth_tests_sim
stage=$(mktemp -d)
trap 'rm -rf "$stage"' EXIT
mkdir -p "$stage/bin" "$stage/lib"
bins=(build/bin/mgcloth build/tests/mgcloth_tests_cuda build/tests/mgcloth_tests_solvers build/tests/mgcloth_tests_sim)
cp "${bins[@]}" "$stage/bin/"
for b in "${bins[@]}"; do ldd "$b"; done | awk '/=> \// {print $3}' | sort -u | while read -r lib; do
  case "$(basename "$lib")" in
    libc.so*|libm.so*|libdl.so*|libpthread.so*|librt.so*|ld-linux*|libgcc_s.so*|libstdc++.so*) ;;
    *) cp -L "$lib" "$stage/lib/" ;;
  esac
done
mkdir -p .device
tar -C "$stage" -cJf .device/bundle.tar.xz bin lib
ls -la .device/bundle.tar.xz
