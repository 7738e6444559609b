//! Helpers shared by the `kestrel` end-to-end tests (each test file that
//! uses them declares `mod common;`).
// Each test file uses a subset of these helpers.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// Runs the `kestrel` binary with `args` and returns whether it succeeded,
/// its standard output and its standard error.
pub fn kestrel(args: &[&str]) -> (bool, String, String) {
    output_of(Command::new(env!("CARGO_BIN_EXE_kestrel")).args(args))
}

/// [`kestrel`] run in the working directory `dir`.
pub fn kestrel_in(dir: &Path, args: &[&str]) -> (bool, String, String) {
    output_of(
        Command::new(env!("CARGO_BIN_EXE_kestrel"))
            .args(args)
            .current_dir(dir),
    )
}

fn output_of(cmd: &mut Command) -> (bool, String, String) {
    let out = cmd.output().expect("runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The repository's identified tricopter model (`kestrel.ss.v1`).
pub const MODEL: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../models/tricopter-blackbox-5.json"
);

/// Writes the thesis-sized problem (`kestrel mpc`, horizon 2 in 2 blocks,
/// q1 2000, q2 0.01) of the model file `model` to `out` and returns `out`.
pub fn thesis_problem_of(model: &str, out: &Path) -> PathBuf {
    let (ok, _, err) = kestrel(&[
        "mpc",
        "--model",
        model,
        "--horizon",
        "2",
        "--blocks",
        "2",
        "--q1",
        "2000",
        "--q2",
        "0.01",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    out.to_path_buf()
}

/// The folder `<name>` in this test process's own scratch folder
/// (`kestrel-tests-XXXXXX` in the system's temporary folder, made once
/// per process with an unpredictable name, so never a folder left by an
/// earlier run whose process had the same id), created if missing: the
/// same name gives the same folder within one process.
pub fn temp_dir(name: &str) -> PathBuf {
    static ROOT: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    let root = ROOT.get_or_init(|| {
        tempfile::Builder::new()
            .prefix("kestrel-tests-")
            .tempdir()
            .unwrap()
            .keep()
    });
    let d = root.join(name);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// [`kestrel`] with a deadline: `None` when it is still running after
/// `seconds` (it is then killed), so a test of a command that used to hang
/// fails instead of hanging.
pub fn kestrel_within(seconds: u64, args: &[&str]) -> Option<(bool, String, String)> {
    let mut child = Command::new(env!("CARGO_BIN_EXE_kestrel"))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("runs");
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(seconds);
    // Read both pipes on threads so a full pipe cannot stall the child.
    let mut out = child.stdout.take().expect("piped");
    let mut err = child.stderr.take().expect("piped");
    let out_t = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = std::io::Read::read_to_string(&mut out, &mut s);
        s
    });
    let err_t = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = std::io::Read::read_to_string(&mut err, &mut s);
        s
    });
    loop {
        if let Some(status) = child.try_wait().expect("waits") {
            let stdout = out_t.join().unwrap_or_default();
            let stderr = err_t.join().unwrap_or_default();
            return Some((status.success(), stdout, stderr));
        }
        if std::time::Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
}

/// Sends SIGINT (Ctrl-C) to the process `pid`.
pub fn interrupt(pid: u32) {
    let ok = Command::new("kill")
        .args(["-INT", &pid.to_string()])
        .status()
        .expect("runs kill")
        .success();
    assert!(ok, "kill -INT {pid} failed");
}

/// Writes `rows` samples at 50 Hz of `kestrel_sysid::synthetic::random_model(n,
/// nu, ny, model_seed, 0.9)` simulated with noise 0.05 and seed
/// `noise_seed` to `path`, as the CSV `t,<names>` (`names`: the inputs'
/// then the outputs' column names, comma separated).
pub fn write_synthetic_log(
    path: &Path,
    (n, nu, ny, model_seed): (usize, usize, usize, u64),
    (rows, noise_seed): (usize, u64),
    names: &str,
) {
    use kestrel_sysid::synthetic;
    let m = synthetic::random_model(n, nu, ny, model_seed, 0.9);
    let d = synthetic::simulate(&m, rows, 0.05, noise_seed).unwrap();
    let e = &d.experiments()[0];
    let mut text = format!("t,{names}\n");
    for k in 0..rows {
        text.push_str(&format!("{:.2}", k as f64 * 0.02));
        for v in e.u.row(k).iter().chain(e.y.row(k).iter()) {
            text.push_str(&format!(",{v}"));
        }
        text.push('\n');
    }
    std::fs::write(path, text).unwrap();
}
