#!/usr/bin/env bash
# The whole test suite from a fresh machine: set-up (idempotent), then every test of the workspace,
# built once in the test profile. Extra arguments go to `cargo test`.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bash scripts/setup.sh
cargo test --workspace --locked "$@"
