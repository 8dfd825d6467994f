//! With the `learn` feature, makes libtorch's shared libraries reachable from every process cargo
//! starts (tests, doctests, `cargo run`): cargo puts native search paths that lie inside the target
//! folder on the loader path, so libtorch's `lib` is linked into OUT_DIR and declared from there.
//! (Binaries run directly find it through the rpath set in `.cargo/config.toml`.)

fn main() {
    println!("cargo:rerun-if-env-changed=LIBTORCH");
    if std::env::var_os("CARGO_FEATURE_LEARN").is_none() {
        return;
    }
    let Some(libtorch) = std::env::var_os("LIBTORCH") else { return };
    let lib = std::path::Path::new(&libtorch).join("lib");
    let out = std::path::PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR")).join("libtorch-lib");
    let _ = std::fs::remove_file(&out);
    #[cfg(unix)]
    if std::os::unix::fs::symlink(&lib, &out).is_ok() {
        println!("cargo:rustc-link-search=native={}", out.display());
    }
}
