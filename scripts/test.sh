#!/usr/bin/env bash
# The whole test suite from a fresh machine: set-up (idempotent), then every test of the workspace,
# built once in the test profile. Extra arguments go to `cargo test`.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bash scripts/setup.sh
# Tests run in parallel; one libtorch thread each avoids oversubscribing the cores (on 2 cores, libtorch's
# default of one thread per core per test made training tests many times slower).
export OMP_NUM_THREADS="${OMP_NUM_THREADS:-1}"
cargo test --workspace --locked "$@"
