//! Property tests: the readers (BVH, URDF, joint mapping, training and dataset configurations,
//! checkpoints) on thousands of mutated copies of real files. None may panic, and every error must
//! name the file it was given. The `fuzz/` crate runs the same readers under libFuzzer for longer.

use std::collections::BTreeMap;
use std::path::Path;

use ace_models::human::{HumanClip, ImportOptions, JointMapping};
use ace_models::urdf::parse_urdf;
use proptest::prelude::*;

fn asset(rel: &str) -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(rel)).unwrap()
}

/// One edit of a text: what BVH and URDF writers and careless users get wrong.
#[derive(Clone, Debug)]
enum Edit {
    /// Remove `len` bytes at `at` (a truncated or damaged file).
    Delete { at: usize, len: usize },
    /// Insert a token at `at`.
    Insert { at: usize, token: &'static str },
    /// Copy `len` bytes from `from` to `at` (duplicated joints, lines, tags).
    Duplicate { from: usize, len: usize, at: usize },
    /// Replace the number starting at or after `at` with a token.
    Number { at: usize, token: &'static str },
}

const TOKENS: &[&str] = &[
    "{",
    "}",
    "\n",
    " ",
    "JOINT X",
    "End Site",
    "OFFSET",
    "CHANNELS 99",
    "MOTION",
    "Frames: 0",
    "nan",
    "inf",
    "-",
    "1e30",
    "-1e30",
    "1e-30",
    "0",
    "99999999999999999999",
    "<",
    ">",
    "</link>",
    "<joint",
    "\"",
    "&",
    "\u{feff}",
    "\u{0}",
    "é",
    "=",
    "[",
    "]",
    "[[x]]",
];

fn edit() -> impl Strategy<Value = Edit> {
    let token = prop::sample::select(TOKENS);
    prop_oneof![
        (any::<usize>(), 1..64usize).prop_map(|(at, len)| Edit::Delete { at, len }),
        (any::<usize>(), token.clone()).prop_map(|(at, token)| Edit::Insert { at, token }),
        (any::<usize>(), 1..400usize, any::<usize>()).prop_map(|(from, len, at)| Edit::Duplicate { from, len, at }),
        (any::<usize>(), token).prop_map(|(at, token)| Edit::Number { at, token }),
    ]
}

/// The largest char boundary of `s` not after `i % (len + 1)`.
fn boundary(s: &str, i: usize) -> usize {
    let mut i = i % (s.len() + 1);
    while !s.is_char_boundary(i) {
        i -= 1;
    }
    i
}

fn apply(text: &str, edits: &[Edit]) -> String {
    let mut s = text.to_string();
    for e in edits {
        match *e {
            Edit::Delete { at, len } => {
                let a = boundary(&s, at);
                let b = boundary(&s, a + len.min(s.len() - a));
                s.replace_range(a..b, "");
            }
            Edit::Insert { at, token } => {
                let a = boundary(&s, at);
                s.insert_str(a, token);
            }
            Edit::Duplicate { from, len, at } => {
                let a = boundary(&s, from);
                let b = boundary(&s, a + len.min(s.len() - a));
                let piece = s[a..b].to_string();
                let at = boundary(&s, at);
                s.insert_str(at, &piece);
            }
            Edit::Number { at, token } => {
                let a = boundary(&s, at);
                if let Some(k) = s[a..].find(|c: char| c.is_ascii_digit()) {
                    let start = a + k;
                    let end = s[start..]
                        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
                        .map_or(s.len(), |e| start + e);
                    s.replace_range(start..end, token);
                }
            }
        }
    }
    s
}

fn cases(n: u32) -> ProptestConfig {
    ProptestConfig {
        cases: n,
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

proptest! {
    #![proptest_config(cases(3000))]
    #[test]
    fn bvh_import_never_panics(edits in prop::collection::vec(edit(), 1..6)) {
        let text = apply(&asset("assets/motions/walk.bvh"), &edits);
        if let Err(e) = HumanClip::from_bvh_str(&text, "mutated.bvh", &ImportOptions { fps: Some(30.0), mapping: None }) {
            let msg = e.to_string();
            prop_assert!(msg.starts_with("mutated.bvh"), "{}", msg);
        }
    }
}

proptest! {
    #![proptest_config(cases(3000))]
    #[test]
    fn urdf_loading_never_panics(edits in prop::collection::vec(edit(), 1..6)) {
        let text = apply(&asset("assets/characters/spot.urdf"), &edits);
        match parse_urdf(&text, "mutated.urdf", None) {
            Err(e) => prop_assert!(e.to_string().starts_with("mutated.urdf: "), "{}", e),
            Ok(tree) => {
                // A tree that loads is usable: its morphology is found or refused with an error.
                let _ = ace_models::morphology::Morphology::analyze(&tree);
            }
        }
    }
}

proptest! {
    #![proptest_config(cases(3000))]
    #[test]
    fn configuration_and_mapping_parsers_never_panic(edits in prop::collection::vec(edit(), 1..5), which in 0..4usize) {
        let base = [
            "steps = 40\nbatch_size = 8\nw_fea = 10.0\ndevice = \"cpu\"\n[feature_weights]\nroot_height = 1.0\n",
            "steps = 120\nbatch_size = 16\nencoder_hidden = [32, 32]\n[sampling]\nstart = 0.1\n",
            "frames = 3000\nfps = 30.0\nepisode_seconds = [8.0, 24.0]\n",
            "pelvis = \"Hips\"\nunit = \"cm\"\nup = \"y\"\nfirst_frame_is_rest_pose = false\n",
        ][which];
        let text = apply(base, &edits);
        match which {
            0 => if let Ok(c) = toml::from_str::<ace_models::learn::ace::AceConfig>(&text) { let _ = c.check(); },
            1 => if let Ok(c) = toml::from_str::<ace_models::learn::prior::PriorConfig>(&text) { let _ = c.check(); },
            2 => if let Ok(c) = toml::from_str::<ace_models::dataset::DatasetConfig>(&text) {
                let _ = ace_models::dataset::check_config(&c);
            },
            _ => if let Err(e) = JointMapping::from_toml_str(&text) {
                prop_assert!(e.to_string().starts_with("joint mapping: invalid joint mapping"), "{}", e);
            },
        }
    }
}

/// The shipped Stretch checkpoint's files, read once.
fn checkpoint_files() -> &'static BTreeMap<String, Vec<u8>> {
    static FILES: std::sync::OnceLock<BTreeMap<String, Vec<u8>>> = std::sync::OnceLock::new();
    FILES.get_or_init(|| {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/checkpoints/stretch");
        ["config.json", "prior.safetensors", "ace.json", "generator.safetensors"]
            .iter()
            .map(|f| (f.to_string(), std::fs::read(dir.join(f)).unwrap()))
            .collect()
    })
}

proptest! {
    // Each load builds the networks: a few dozen cases keep this in seconds; `fuzz/` goes further.
    #![proptest_config(cases(40))]
    #[test]
    fn checkpoint_loading_never_panics(file in 0..4usize, flips in prop::collection::vec((any::<usize>(), any::<u8>()), 1..8), cut in prop::option::of(any::<usize>())) {
        let mut files = checkpoint_files().clone();
        let name = ["config.json", "prior.safetensors", "ace.json", "generator.safetensors"][file];
        let bytes = files.get_mut(name).unwrap();
        // Metadata files get byte flips anywhere; weights files in the header, where the structure is.
        let span = if name.ends_with(".json") { bytes.len() } else { bytes.len().min(4096) };
        for (at, v) in &flips {
            bytes[at % span] = *v;
        }
        if let Some(c) = cut {
            bytes.truncate(c % (bytes.len() + 1));
        }
        let dir = Path::new("mutated-checkpoint");
        let loaded = ace_models::learn::retarget::Retargeter::load_files(
            &ace_models::learn::CheckpointFiles::in_memory(dir, files),
            ace_models::learn::Device::Cpu,
        );
        if let Err(e) = loaded {
            prop_assert!(e.to_string().contains("mutated-checkpoint"), "{}", e);
        }
    }
}

// The pure-Rust checkpoint loader (`ace_models::runtime`), the one the plugin and `ace retarget` use
// by default: no libtorch and no networks built in libtorch, so hundreds of cases run in seconds.
// Metadata files get text edits and byte flips anywhere; weights files get their safetensors header
// edited (tensors renamed or removed, other dtypes, shapes and offsets) and mangled as text, byte
// flips anywhere in the file (the header and the tensor data well beyond the first 4 KB) and
// truncation, with the metadata recording the mutated file's checksum in half the cases (so that the
// checks behind it are reached too). A load that fails names a file of the checkpoint; one that
// succeeds gives a retargeter that starts on its character.

const CHECKPOINT_FILES: [&str; 4] = ["config.json", "prior.safetensors", "ace.json", "generator.safetensors"];

/// The error of a runtime load of `files`, which must name a file of the mutated checkpoint; `None`
/// when it loaded (and then it must start on the Stretch).
fn runtime_load(files: BTreeMap<String, Vec<u8>>) -> Option<String> {
    let dir = Path::new("mutated-checkpoint");
    match ace_models::runtime::Retargeter::load_files(&ace_models::checkpoint::CheckpointFiles::in_memory(dir, files)) {
        Err(e) => Some(e.to_string()),
        Ok(r) => {
            static STRETCH: std::sync::OnceLock<(ace_models::kinematics::KinematicTree, ace_models::morphology::Morphology)> =
                std::sync::OnceLock::new();
            let (tree, morph) = STRETCH.get_or_init(|| {
                ace_models::morphology::load_character(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/characters/stretch.urdf"))
                    .unwrap()
            });
            // A checkpoint that loads is usable: it accepts its character or refuses it with an error.
            if r.check_character(tree, morph).is_ok() {
                let _ = r.start_state(tree, morph);
            }
            None
        }
    }
}

/// Whether `e` names a file of the mutated checkpoint.
fn names_a_checkpoint_file(e: &str) -> bool {
    CHECKPOINT_FILES.iter().any(|f| e.contains(&format!("mutated-checkpoint/{f}")))
}

proptest! {
    #![proptest_config(cases(500))]
    #[test]
    fn runtime_checkpoint_metadata_mutations_are_errors_naming_the_file(
        file in 0..2usize,
        edits in prop::collection::vec(edit(), 0..5),
        flips in prop::collection::vec((any::<usize>(), any::<u8>()), 0..4),
    ) {
        let mut files = checkpoint_files().clone();
        let name = ["config.json", "ace.json"][file];
        let text = String::from_utf8(files[name].clone()).unwrap();
        let mut bytes = apply(&text, &edits).into_bytes();
        for (at, v) in &flips {
            let n = bytes.len();
            if n > 0 {
                bytes[at % n] = *v;
            }
        }
        files.insert(name.to_string(), bytes);
        if let Some(e) = runtime_load(files) {
            prop_assert!(names_a_checkpoint_file(&e), "{}", e);
        }
    }
}

/// A structural edit of a safetensors header (the JSON map from tensor name to dtype, shape and
/// offsets), on tensor `k` (modulo their number): what a text edit rarely reaches without breaking the
/// JSON.
#[derive(Clone, Debug)]
enum HeaderEdit {
    /// Another name (a variable the network does not have, and one it misses).
    Rename(usize, &'static str),
    /// Another dtype; I32 and U32 keep the byte size, so the file still parses.
    Dtype(usize, &'static str),
    /// The dimensions reversed or flattened (same element count), or replaced.
    Shape(usize, Option<Vec<u64>>),
    /// Other data offsets.
    Offsets(usize, u64, u64),
    /// The tensor removed.
    Remove(usize),
}

fn header_edit() -> impl Strategy<Value = HeaderEdit> {
    prop_oneof![
        (any::<usize>(), prop::sample::select(&["x", "generator.layer9.weight", "decoder.gate", "", "\u{0}"][..]))
            .prop_map(|(k, n)| HeaderEdit::Rename(k, n)),
        (any::<usize>(), prop::sample::select(&["I32", "U32", "F16", "F64", "BOOL", "X"][..]))
            .prop_map(|(k, d)| HeaderEdit::Dtype(k, d)),
        (any::<usize>(), prop::option::of(prop::collection::vec(prop::sample::select(&[0u64, 1, 3, 256, 1 << 40, u64::MAX][..]), 0..4)))
            .prop_map(|(k, s)| HeaderEdit::Shape(k, s)),
        (any::<usize>(), any::<u64>(), any::<u64>()).prop_map(|(k, a, b)| HeaderEdit::Offsets(k, a % 1_000_000, b % 1_000_000)),
        any::<usize>().prop_map(HeaderEdit::Remove),
    ]
}

/// `header` (safetensors JSON) with `edits` applied.
fn apply_header(header: &str, edits: &[HeaderEdit]) -> String {
    let mut map: serde_json::Map<String, serde_json::Value> = serde_json::from_str(header).unwrap();
    for e in edits {
        let names: Vec<String> = map.keys().filter(|k| *k != "__metadata__").cloned().collect();
        if names.is_empty() {
            break;
        }
        let pick = |k: usize| names[k % names.len()].clone();
        match e {
            HeaderEdit::Rename(k, to) => {
                let v = map.remove(&pick(*k)).unwrap();
                map.insert(to.to_string(), v);
            }
            HeaderEdit::Dtype(k, d) => map[&pick(*k)]["dtype"] = (*d).into(),
            HeaderEdit::Shape(k, shape) => {
                let t = &mut map[&pick(*k)];
                let dims: Vec<u64> = t["shape"].as_array().unwrap().iter().map(|d| d.as_u64().unwrap()).collect();
                let new = match shape {
                    Some(s) => s.clone(),
                    None if dims.len() > 1 => dims.iter().rev().copied().collect(),
                    None => vec![dims.iter().product()],
                };
                t["shape"] = new.into();
            }
            HeaderEdit::Offsets(k, a, b) => map[&pick(*k)]["data_offsets"] = vec![*a, *b].into(),
            HeaderEdit::Remove(k) => {
                map.remove(&pick(*k));
            }
        }
    }
    serde_json::Value::Object(map).to_string()
}

/// One kind of damage to a weights file per case, so that each is tried often on its own.
#[derive(Clone, Debug)]
enum WeightsMutation {
    /// Structural edits of the header ([`HeaderEdit`]).
    Header(Vec<HeaderEdit>),
    /// Text edits of the header.
    HeaderText(Vec<Edit>),
    /// Byte flips in the length prefix and the header.
    HeaderFlips(Vec<(usize, u8)>),
    /// Byte flips in the tensor data, past the first 4 KB.
    DataFlips(Vec<(usize, u8)>),
    /// The file cut short.
    Cut(usize),
}

fn weights_mutation() -> impl Strategy<Value = WeightsMutation> {
    let flips = || prop::collection::vec((any::<usize>(), any::<u8>()), 1..6);
    prop_oneof![
        prop::collection::vec(header_edit(), 1..3).prop_map(WeightsMutation::Header),
        prop::collection::vec(edit(), 1..4).prop_map(WeightsMutation::HeaderText),
        flips().prop_map(WeightsMutation::HeaderFlips),
        flips().prop_map(WeightsMutation::DataFlips),
        any::<usize>().prop_map(WeightsMutation::Cut),
    ]
}

proptest! {
    #![proptest_config(cases(600))]
    #[test]
    fn runtime_checkpoint_weights_mutations_are_errors_naming_the_file(
        file in 0..2usize,
        mutation in weights_mutation(),
        rerecord in any::<bool>(),
    ) {
        let mut files = checkpoint_files().clone();
        let name = ["prior.safetensors", "generator.safetensors"][file];
        let mut bytes = files[name].clone();
        let n = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
        let header = String::from_utf8(bytes[8..8 + n].to_vec()).unwrap();
        // The header edited, with its length prefix rewritten.
        let rewrite = |edited: String| {
            let mut out = (edited.len() as u64).to_le_bytes().to_vec();
            out.extend_from_slice(edited.as_bytes());
            out.extend_from_slice(&bytes[8 + n..]);
            out
        };
        let len = bytes.len();
        let mutated = match &mutation {
            WeightsMutation::Header(edits) => rewrite(apply_header(&header, edits)),
            WeightsMutation::HeaderText(edits) => rewrite(apply(&header, edits)),
            WeightsMutation::HeaderFlips(flips) => {
                for (at, v) in flips {
                    bytes[at % (8 + n)] = *v;
                }
                bytes
            }
            // The whole file is checksummed and every value checked for NaN and infinity.
            WeightsMutation::DataFlips(flips) => {
                for (at, v) in flips {
                    bytes[4096 + at % (len - 4096)] = *v;
                }
                bytes
            }
            WeightsMutation::Cut(c) => {
                bytes.truncate(c % len);
                bytes
            }
        };
        let unchanged = mutated == files[name];
        if rerecord {
            // The metadata records the mutated file's size and checksum, as if it had been saved so:
            // the structure and value checks behind the checksum are reached.
            let record = serde_json::to_value(ace_models::checkpoint::FileRecord::of(name, &mutated)).unwrap();
            for (meta, key) in [("config.json", "weights"), ("ace.json", "prior"), ("ace.json", "generator")] {
                let mut v: serde_json::Value = serde_json::from_slice(&files[meta]).unwrap();
                if v[key]["file"] == name {
                    v[key] = record.clone();
                    files.insert(meta.to_string(), serde_json::to_vec(&v).unwrap());
                }
            }
        }
        files.insert(name.to_string(), mutated);
        match runtime_load(files) {
            Some(e) => prop_assert!(names_a_checkpoint_file(&e), "{}", e),
            // Every byte of a weights file is recorded by its checksum: only the file itself loads,
            // unless the metadata records the change.
            None => prop_assert!(unchanged || rerecord, "a changed {} loaded", name),
        }
    }
}
