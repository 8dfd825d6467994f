#!/usr/bin/env bash
# One-time, idempotent set-up for building and testing the project on Debian/Ubuntu:
#   * the Debian packages Bevy links against (and Xvfb + software Vulkan for the editor's screenshots),
#   * libtorch 2.13.0 from the registry's `torch==2.13.0` wheel, in a project-local venv,
#   * `.local/libtorch`, the stable path that `.cargo/config.toml` points tch at (build and run time),
#   * Khronos' glTF validator from npm in `.local/node` (Node.js from Debian if missing), for the export tests.
# After it, plain `cargo build`, `cargo test` and `cargo run` work with no environment variables.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
local_dir="$root/.local"
venv="$local_dir/torch-venv"
torch_version="2.13.0"

log() { printf '\033[1;34m[setup]\033[0m %s\n' "$*"; }

debian_packages=(
  pkg-config build-essential
  libudev-dev libasound2-dev libwayland-dev libxkbcommon-dev libx11-dev libxi-dev libxcursor-dev libxrandr-dev
  xvfb xauth mesa-vulkan-drivers libvulkan1 libgl1-mesa-dri
  python3-venv
)

if command -v apt-get >/dev/null 2>&1; then
  missing=()
  for p in "${debian_packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if ((${#missing[@]})); then
    sudo_cmd=""
    [ "$(id -u)" -eq 0 ] || sudo_cmd="sudo"
    log "installing Debian packages: ${missing[*]}"
    $sudo_cmd apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -qq --no-install-recommends "${missing[@]}"
  else
    log "Debian packages present"
  fi
else
  log "apt-get not found: install the equivalents of ${debian_packages[*]} by your system's means"
fi

mkdir -p "$local_dir"
py="${PYTHON:-python3}"
if [ ! -x "$venv/bin/python" ]; then
  log "creating venv $venv"
  "$py" -m venv "$venv"
fi
have="$("$venv/bin/python" -c 'import importlib.metadata as m; print(m.version("torch"))' 2>/dev/null || true)"
if [ "$have" != "$torch_version" ]; then
  log "installing torch==$torch_version (libtorch for tch; a few minutes, ~4.7 GB)"
  "$venv/bin/python" -m pip install -q --disable-pip-version-check "torch==$torch_version"
else
  log "torch $torch_version present"
fi
# A relative link: it stays valid when .local is reached through another path (a linked copy).
torch_dir="$("$venv/bin/python" -c 'import os, sys, torch; print(os.path.relpath(os.path.dirname(torch.__file__), sys.argv[1]))' "$local_dir")"
ln -sfn "$torch_dir" "$local_dir/libtorch"
test -f "$local_dir/libtorch/lib/libtorch_cpu.so" || { echo "setup: $local_dir/libtorch/lib/libtorch_cpu.so missing" >&2; exit 1; }
log "libtorch at $local_dir/libtorch -> $torch_dir"

# Khronos' glTF validator (npm `gltf-validator`, pinned) in `.local/node`, for checking exported GLB
# files: `node scripts/validate-gltf.mjs FILE.glb` (the export tests run it).
gltf_validator_version="2.0.0-dev.3.10"
node_dir="$local_dir/node"
if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
  if command -v apt-get >/dev/null 2>&1; then
    sudo_cmd=""
    [ "$(id -u)" -eq 0 ] || sudo_cmd="sudo"
    log "installing Debian packages: nodejs npm"
    $sudo_cmd apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -qq --no-install-recommends nodejs npm
  else
    echo "setup: node and npm are needed for the glTF validator; install Node.js by your system's means" >&2
    exit 1
  fi
fi
have="$(cd "$node_dir" 2>/dev/null && node -p "require('gltf-validator/package.json').version" 2>/dev/null || true)"
if [ "$have" != "$gltf_validator_version" ]; then
  log "installing gltf-validator@$gltf_validator_version into $node_dir"
  mkdir -p "$node_dir"
  npm install --prefix "$node_dir" --save-exact --no-audit --no-fund --loglevel=error \
    "gltf-validator@$gltf_validator_version"
else
  log "gltf-validator $gltf_validator_version present"
fi
