#!/bin/sh
# Seeds the fuzz corpora from the shared data and the project's assets (copied at run time, never
# committed: fuzz/corpus is ignored).
set -e
here=$(dirname "$0")
data="$here/../../shared/data"
mkdir -p "$here/corpus/bvh" "$here/corpus/urdf" "$here/corpus/config" "$here/corpus/checkpoint" "$here/corpus/gltf"
find "$data/human" -name '*.bvh' -size -200k | head -200 | while read -r f; do cp "$f" "$here/corpus/bvh/"; done
cp "$here"/../assets/motions/*.bvh "$here/corpus/bvh/"
find "$data/robots" -name '*.urdf' -exec cp {} "$here/corpus/urdf/" \;
cp "$here"/../assets/characters/*.urdf "$here/corpus/urdf/"
find "$data/creatures" -name '*.glb' -size -2M -exec cp {} "$here/corpus/gltf/" \;
cp "$here"/../assets/creatures/*.glb "$here/corpus/gltf/"
cp "$here"/../models/tests/data/*.toml "$here/corpus/config/"
printf 'steps = 40\nbatch_size = 8\n[feature_weights]\nroot_height = 1.0\n' > "$here/corpus/config/ace.toml"
printf 'frames = 3000\nfps = 30.0\n' > "$here/corpus/config/dataset.toml"
python3 - "$here" <<'PY'
import struct, sys
here = sys.argv[1]
for c in ["spot", "crab", "stretch"]:
    d = f"{here}/../assets/checkpoints/{c}"
    out = b""
    for k, name in enumerate(["config.json", "prior.safetensors", "ace.json", "generator.safetensors"]):
        data = open(f"{d}/{name}", "rb").read()
        out += data if k == 3 else struct.pack("<I", len(data)) + data
    open(f"{here}/corpus/checkpoint/{c}", "wb").write(out)
PY
