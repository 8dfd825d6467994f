#!/usr/bin/env bash
# The web check of issue 18: the runtime parts of the core (`ace_models` without `learn`) and of the
# plugin (`bevy_ace` with `runtime`, `scene` and `render`, no `learn`) type-check for
# wasm32-unknown-unknown. Not part of the test suite: a cold check takes about 25 minutes on two cores
# (measured: 6.8 min for the core, 18 min for the plugin with Bevy). It is a check, not a port: the
# plugin's Retargeter runs its networks on a worker thread, which wasm32-unknown-unknown cannot start.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
rustup target add wasm32-unknown-unknown
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target/wasm}"
cargo check --locked --target wasm32-unknown-unknown -p ace_models --no-default-features
cargo check --locked --target wasm32-unknown-unknown -p bevy_ace --no-default-features --features runtime,scene,render
echo "check-wasm: ace_models and bevy_ace (runtime) type-check for wasm32-unknown-unknown"
