#!/usr/bin/env bash
# Mutation testing of the core modules whose correctness the tests must guard: cargo-mutants plants
# one small bug at a time (a `<` for a `<=`, a function returning a default, a `+` for a `-`) and runs
# the tests aimed at that file; a mutant the tests do not fail on is a gap in them.
#
#   bash scripts/mutants.sh [FILE...]      (default: every file listed below)
#
# Not part of CI: each mutant rebuilds and reruns tests, about half a minute to two minutes each on
# 2 cores (the files below have 27 to 187 mutants each). cargo-mutants (pinned) is installed into
# .local/cargo on first use. It mutates the committed HEAD in a worktree beside this checkout
# (`../<checkout>-mutants`, so that the tests find ../shared as they do here; uncommitted changes are
# not in it), never this checkout's files. Each file's results go to out/mutants/<file, slashes as
# dashes>/mutants.out ({caught,missed,timeout,unviable}.txt, outcomes.json), and a table of them is
# printed at the end.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
version="27.1.0"
bin="$root/.local/cargo/bin/cargo-mutants"
if ! "$bin" mutants --version 2>/dev/null | grep -q "$version"; then
  echo "mutants: installing cargo-mutants $version into .local/cargo (a few minutes)"
  cargo install --locked --quiet --root "$root/.local/cargo" cargo-mutants --version "$version"
fi
export PATH="$root/.local/cargo/bin:$PATH"
# One libtorch thread per test, as in scripts/test.sh.
export OMP_NUM_THREADS="${OMP_NUM_THREADS:-1}"

# Per file: the cargo-mutants options that build its crate (package, features, and for the learning
# modules the functions mutated) and the tests aimed at it (cargo test arguments, then `--` and the test
# binaries' filter). `ufr.rs` also runs the crate's unit tests: its pose checks are the collision guard's
# and the foot lock's, tested there. Learning modules need the `learn` feature (libtorch); the rest of
# the core builds without it, which is much faster. The learning modules' networks are exercised by the
# training, retargeting and runtime tests of other modules, so all of the crate's unit tests run for
# them (about 15 s); in `train_ace.rs` and `prior.rs` only the code that starts, resumes or fine-tunes a
# run is mutated (each mutant relinks libtorch, about a minute; the training loops themselves are
# checked by the end-to-end runs). The plugin's `retarget.rs` runs its crate's own Retargeter tests
# (`plugin/tests/retarget.rs`, no libtorch); the rigged creatures' scene tests stay in the `ace` crate,
# which trains their small checkpoints with the `ace` binary. The pure-Rust networks (`runtime/nets.rs`)
# are checked against libtorch's by the runtime's equivalence tests, so they need `learn` too. The BVH
# reader runs its import tests and unit tests; the hostile-input tests (`reliability`, `mutated_inputs`)
# also read checkpoints and need `learn`, so they are run by hand on its survivors. Forward kinematics
# runs every test binary of the core that poses characters without training (a few seconds); the
# self-collision geometry (UFR's, the collision guard's) its own unit tests, which hold its narrow
# phase to references computed another way, and the metrics' tests. The URDF reader runs the import
# tests (its errors word for word); the hostile-input tests are run by hand on its survivors, as for
# the BVH reader. The matching of a BVH's joints to the canonical skeleton runs the import tests (every
# shared clip's sources per convention) and the unit tests; the human state x^h also the following and
# metrics tests, which read it; the reading of joint names, the length units and up axes, what the
# importer infers from the posed skeleton, the per-frame tracks, the BVH's forward kinematics, the
# clip (timing, resampling, warnings) and the import pipeline (its checks of absurd values) the import
# tests and the unit tests; the hostile-input tests of the last two are run by hand on their survivors.
# Reaching (the arms' and leftover DoFs' targets, paths and timing) runs the controller tests on the
# bundled and shared robots and the crate's unit tests (its own, on an arm written in the test). The
# glTF export and its writer run the export tests (the bundled and shared robots read back node by
# node, the writer's own on the buffer, accessors, animation and GLB container; the Khronos
# validator runs only where `.local/node` is installed, so not in the worktree). The character state
# x^r runs its own unit tests (on the bundled Spot; they catch every viable mutant but one exact tie,
# and take a second where the import and dataset tests that also read x^r take fifteen). Of the glTF
# import only its helpers are mutated, against their unit tests (URI escapes, base64, placements, the
# polar rotation, capsule fitting): the rest of the reader is checked by the creature tests, which take
# too long per mutant. A clip on a creature's own model (`export/rig.rs`) runs the rig export tests
# (the shared creatures' clips written, read back and validated where the validator is installed).
# The morphology analysis (feet, manipulators, wheels, head of a URDF robot; the profile's overrides)
# runs the URDF import tests (the bundled and shared robots' body plans) and the unit tests.
core="--package ace_models --no-default-features"
learn="--package ace_models --features learn"
declare -A how=(
  [models/src/features.rs]="$core -- --test metrics"
  [models/src/metrics/ufr.rs]="$core -- --test metrics --lib"
  [models/src/metrics/distribution.rs]="$core -- --test metrics"
  [models/src/metrics/joint_limits.rs]="$core -- --test joint_limits"
  [models/src/controller/joint_speed.rs]="$core -- --test joint_limits --lib -- joint_speed leg_limits legs_within hexapods_legs"
  [models/src/metrics/gait.rs]="$core -- --test gait --lib"
  [models/src/dynamic_similarity.rs]="$core -- --test gait --test controllers --lib"
  [models/src/foot_lock.rs]="$core -- --lib -- foot_lock"
  [models/src/collision_guard.rs]="$core -- --lib -- collision_guard"
  [models/src/heading.rs]="$core -- --lib -- heading"
  [models/src/standing.rs]="$core -- --lib -- standing"
  [models/src/effector_hold.rs]="$core -- --lib -- effector_hold"
  [models/src/velocity_limit.rs]="$core -- --lib -- velocity_limit"
  [models/src/correspondence.rs]="$core -- --lib -- correspondence"
  [models/src/metrics/following.rs]="$core -- --test following --lib"
  [models/src/human/bvh.rs]="$core -- --test human_import --lib"
  [models/src/human/matching.rs]="$core -- --test human_import --lib"
  [models/src/human/names.rs]="$core -- --test human_import --lib"
  [models/src/human/units.rs]="$core -- --test human_import --lib"
  [models/src/human/detect.rs]="$core -- --test human_import --lib"
  [models/src/human/tracks.rs]="$core -- --test human_import --lib"
  [models/src/human/fk.rs]="$core -- --test human_import --lib"
  [models/src/human/clip.rs]="$core -- --test human_import --lib"
  [models/src/human/import.rs]="$core -- --test human_import --lib"
  [models/src/human/state.rs]="$core -- --test human_import --test following --test metrics --lib"
  [models/src/controller/reach.rs]="$core -- --test controllers --lib"
  [models/src/export/gltf.rs]="$core -- --lib -- export"
  [models/src/export/writer.rs]="$core -- --lib -- export"
  [models/src/character_state.rs]="$core -- --lib -- character_state"
  [models/src/character/gltf.rs]="$core --re percent_decode|decode_base64|same_placement|polar_rotation|fit_capsule -- --lib -- character::gltf"
  [models/src/export/rig.rs]="$core -- --test rig_export"
  [models/src/morphology.rs]="$core -- --test character_import --lib"
  [models/src/kinematics.rs]="$core -- --test metrics --test character_import --test controllers --test creatures --lib"
  [models/src/metrics/collision.rs]="$core -- --test metrics --lib"
  [models/src/urdf.rs]="$core -- --test character_import --test metrics --lib"
  [models/src/runtime/nets.rs]="$learn -- --lib -- runtime"
  [models/src/learn/ace.rs]="$learn -- --lib"
  [models/src/learn/train_ace.rs]="$learn --re start_or_resume|start_fine_tune|place_prior -- --lib"
  [models/src/learn/prior.rs]="$learn --re start_or_resume -- --lib"
  [plugin/src/retarget.rs]="--package bevy_ace -- --test retarget"
)
order=(models/src/features.rs models/src/metrics/ufr.rs models/src/metrics/distribution.rs
       models/src/metrics/joint_limits.rs models/src/controller/joint_speed.rs
       models/src/metrics/gait.rs models/src/dynamic_similarity.rs
       models/src/foot_lock.rs models/src/collision_guard.rs models/src/heading.rs
       models/src/standing.rs models/src/effector_hold.rs models/src/velocity_limit.rs
       models/src/correspondence.rs models/src/metrics/following.rs models/src/human/bvh.rs
       models/src/human/matching.rs models/src/human/names.rs models/src/human/units.rs
       models/src/human/detect.rs models/src/human/tracks.rs models/src/human/fk.rs
       models/src/human/clip.rs models/src/human/import.rs models/src/human/state.rs models/src/kinematics.rs models/src/metrics/collision.rs models/src/urdf.rs
       models/src/controller/reach.rs models/src/export/gltf.rs models/src/export/writer.rs
       models/src/character_state.rs models/src/character/gltf.rs models/src/export/rig.rs
       models/src/morphology.rs
       models/src/runtime/nets.rs
       models/src/learn/ace.rs models/src/learn/train_ace.rs models/src/learn/prior.rs
       plugin/src/retarget.rs)
files=("$@")
[ ${#files[@]} -eq 0 ] && files=("${order[@]}")

for f in "${files[@]}"; do
  [ -n "${how[$f]:-}" ] || { echo "mutants: no tests are listed for $f (see ${BASH_SOURCE[0]})" >&2; exit 2; }
done
tree="$(dirname "$root")/$(basename "$root")-mutants"
if [ -d "$tree" ]; then
  git -C "$tree" checkout --quiet --detach "$(git rev-parse HEAD)"
else
  git worktree add --quiet --detach "$tree" HEAD
fi
ln -sfn "$root/.local" "$tree/.local"
for f in "${files[@]}"; do
  out="$root/out/mutants/${f//\//-}"
  mkdir -p "$out"
  read -r -a opts <<< "${how[$f]}"
  echo "mutants: $f"
  # Exit status 2 means missed mutants, 3 timeouts: the table below says which; go on to the next file.
  (cd "$tree" && cargo mutants --in-place --file "$f" --output "$out" --timeout-multiplier 3 "${opts[@]}") || true
done

printf '\n| file | mutants | caught | missed | timeouts | unviable |\n|---|---:|---:|---:|---:|---:|\n'
for f in "${files[@]}"; do
  d="out/mutants/${f//\//-}/mutants.out"
  count() { local n=0; [ -f "$d/$1.txt" ] && n=$(grep -c . "$d/$1.txt" || true); echo "${n:-0}"; }
  c=$(count caught); m=$(count missed); t=$(count timeout); u=$(count unviable)
  printf '| %s | %d | %d | %d | %d | %d |\n' "$f" $((c + m + t + u)) "$c" "$m" "$t" "$u"
done
