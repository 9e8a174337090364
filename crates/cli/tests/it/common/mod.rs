//! Helpers shared by the end-to-end tests: running the `loam` binary (and interrupting it),
//! the refusals of `loam gradient`, `loam invert` and `loam check` on inversion files.

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

/// Starts `loam ARGS` in the background, its output piped.
#[cfg(unix)]
pub fn spawn_loam(args: &[&str]) -> std::process::Child {
    Command::new(env!("CARGO_BIN_EXE_loam"))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("the loam binary starts")
}

/// Sends SIGINT to `child` once `ready()` holds (asked every 20 ms, for at most `patience_s`
/// seconds) and returns its exit code and stderr.
#[cfg(unix)]
pub fn interrupt_when(
    child: std::process::Child,
    patience_s: u64,
    ready: impl Fn() -> bool,
) -> (Option<i32>, String) {
    use std::time::{Duration, Instant};
    let start = Instant::now();
    while !ready() {
        assert!(
            start.elapsed() < Duration::from_secs(patience_s),
            "not ready after {patience_s} s"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let kill = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(kill.success());
    let out = child.wait_with_output().expect("the process ends");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}
