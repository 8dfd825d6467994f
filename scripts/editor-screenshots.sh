#!/usr/bin/env bash
# Opens the editor on a bundled character (the crab by default, or the one named: spot, stretch, hound), its
# shipped checkpoint and the walk clip under Xvfb (Mesa's software Vulkan, installed by setup.sh) and
# runs its scripted tour: screenshots of the preview, of "Retrain briefly" under way and of its result,
# with the figures in tour.json.
#
#   bash scripts/editor-screenshots.sh [OUT_DIR [CHARACTER]]   (default: docs/editor and crab, whose Retrain briefly runs)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bash scripts/setup.sh
cargo build --locked -p ace_editor
editor="${CARGO_TARGET_DIR:-$root/target}/debug/ace-editor"
out="${1:-docs/editor}"
character="${2:-crab}"
# One libtorch thread: the retraining shares the two cores with the software renderer.
OMP_NUM_THREADS=1 xvfb-run -a -s "-screen 0 1600x900x24" "$editor" --character "$character" --tour "$out"
echo "screenshots and tour.json in $out"
