#!/usr/bin/env bash
# Installs the Debian packages traverse needs, only those missing. Idempotent; quiet when
# everything is present. Needs root (or sudo) only when something must be installed.
set -euo pipefail
pkgs=(build-essential cmake ninja-build pkg-config
      libceres-dev libeigen3-dev libsuitesparse-dev libcli11-dev
      libgtest-dev libgmock-dev libbenchmark-dev libyaml-cpp-dev liburdfdom-dev
      nlohmann-json3-dev
      python3-h5py python3-numpy
      chromium  # the report test renders report.html headless (tests/report_test.cpp)
      clang libclang-rt-14-dev)  # the fuzz preset: clang and its libFuzzer (.ci/run runs it)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
echo "setup: installing ${missing[*]}" >&2
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
