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
