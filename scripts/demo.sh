#!/usr/bin/env bash
# The main job from a fresh machine: set-up (idempotent), then `ace demo` on the bundled defaults.
# Extra arguments go to `ace demo` (see `cargo run -- demo --help`).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bash scripts/setup.sh
cargo run --locked --bin ace -- demo "$@"
