#!/usr/bin/env bash
# Trains the checkpoints shipped in assets/checkpoints/ from scratch, with the project's own CLI and
# the CPU defaults, evaluates each on its held-out human clips and copies the results into place.
#
#   bash scripts/train-checkpoints.sh [spot] [crab] [stretch] [hound]     (default: all four)
#
# Work happens in out/checkpoints/<character> (resumable: rerunning continues an interrupted run) and
# out/eval/<character>; assets/checkpoints/<character> is replaced only once a character is done.
# Per character: `ace train-prior` (with assets/training/<character>.prior.toml and, for its dataset,
# assets/training/<character>.dataset.toml when present),
# `ace train` (with assets/training/<character>.toml when present), `ace eval`. libtorch uses one thread: on this project's 2-core machines that is the fastest setting.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bash scripts/setup.sh
cargo build --locked --bin ace
ace="$root/target/debug/ace"
[ -n "${CARGO_TARGET_DIR:-}" ] && ace="$CARGO_TARGET_DIR/debug/ace"

characters=("$@")
[ ${#characters[@]} -eq 0 ] && characters=(spot crab stretch hound)
for c in "${characters[@]}"; do
    run="out/checkpoints/$c"
    prior_config=()
    [ -f "assets/training/$c.prior.toml" ] && prior_config=(--config "assets/training/$c.prior.toml")
    dataset_config=()
    [ -f "assets/training/$c.dataset.toml" ] && dataset_config=(--dataset-config "assets/training/$c.dataset.toml")
    config=()
    [ -f "assets/training/$c.toml" ] && config=(--config "assets/training/$c.toml")
    start=$(date +%s)
    "$ace" --threads 1 train-prior --character "$c" --checkpoint "$run" "${prior_config[@]}" "${dataset_config[@]}"
    prior_done=$(date +%s)
    "$ace" --threads 1 train --character "$c" --checkpoint "$run" "${config[@]}"
    done_at=$(date +%s)
    "$ace" --threads 1 eval --character "$c" --checkpoint "$run" --out "out/eval/$c"
    echo "$c: prior $(( prior_done - start )) s, ACE $(( done_at - prior_done )) s, total $(( done_at - start )) s"
    dest="assets/checkpoints/$c"
    rm -rf "$dest.new"
    mkdir -p "$dest.new"
    cp "$run"/{config.json,prior.safetensors,ace.json,generator.safetensors,discriminator.safetensors,reference.json} "$dest.new/"
    cp "$run"/{prior_losses.csv,prior_losses.png,ace_losses.csv,ace_losses.png} "$dest.new/"
    cp "out/eval/$c"/eval.{md,csv,json,png} "$dest.new/"
    rm -rf "$dest"
    mv "$dest.new" "$dest"
    echo "$c: shipped in $dest ($(du -sh "$dest" | cut -f1))"
done
