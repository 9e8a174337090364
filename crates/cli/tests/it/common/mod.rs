//! Helpers shared by the end-to-end tests of `loam gradient`, `loam invert` and `loam check`
//! on inversion files (explicit and implicit scenes).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the `loam` binary of this build with `args` and waits for it.
pub fn loam(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_loam"))
        .args(args)
        .output()
        .expect("the loam binary runs")
}

/// A path inside the repository, given relative to its root.
pub fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(path)
}

/// Standard output followed by standard error, as text.
pub fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// Writes each case's inversion file into `dir` and checks that `loam gradient` and
/// `loam check` both exit 2 with one `error: ` line (no panic) that names the case's field
/// path (`field: `) and contains its words.
pub fn assert_refused(dir: &Path, cases: &[(String, &str, &str)]) {
    for (k, (body, field, words)) in cases.iter().enumerate() {
        let path = dir.join(format!("bad{k}.toml"));
        std::fs::write(&path, body).unwrap();
        for cmd in ["gradient", "check"] {
            let out = loam(&[cmd, path.to_str().unwrap()]);
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "{cmd} case {k}: {err}");
            assert!(
                err.starts_with("error: ") && !err.contains("panicked"),
                "{err}"
            );
            assert!(
                err.contains(&format!("{field}: ")) && err.contains(words),
                "case {k}: {err}"
            );
        }
    }
}
