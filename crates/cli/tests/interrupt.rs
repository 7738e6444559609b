//! Long work (issue 20): a command stopped by Ctrl-C (SIGINT) exits with
//! status 130 and leaves no output, partial report or temporary file
//! behind; a long explicit solve is announced before it starts (finding
//! 9); progress is shown on a terminal and nowhere else. Unix only (the
//! tests send SIGINT with `kill`).
#![cfg(unix)]

mod common;
use common::{interrupt, temp_dir};
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Everything in `dir`, hidden files included.
fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Waits up to `seconds` for `child` to exit: its exit code.
fn exit_code(child: &mut Child, seconds: u64) -> Option<i32> {
    let deadline = Instant::now() + Duration::from_secs(seconds);
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            return s.code();
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!("still running {seconds} s after SIGINT");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn ctrl_c_stops_the_pipeline_leaving_no_partial_report() {
    stop_the_pipeline("INT");
}

/// `kill` and `timeout` send SIGTERM: the same clean stop.
#[test]
fn sigterm_stops_the_pipeline_leaving_no_partial_report() {
    stop_the_pipeline("TERM");
}

/// Starts `kestrel pipeline`, sends `signal` once the report is being
/// built, and checks that it stops with 130 and leaves nothing behind.
fn stop_the_pipeline(signal: &str) {
    let dir = temp_dir(&format!("interrupt-pipeline-{signal}"));
    let mut child = Command::new(env!("CARGO_BIN_EXE_kestrel"))
        .args(["pipeline", "--quick", "--out", "report"])
        .current_dir(&dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Interrupt once the report is being built (its staging directory
    // exists), well before the run ends.
    let deadline = Instant::now() + Duration::from_secs(60);
    while entries(&dir).is_empty() {
        assert!(Instant::now() < deadline, "the pipeline never started");
        assert!(
            child.try_wait().unwrap().is_none(),
            "the pipeline ended early"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(1500));
    assert!(
        child.try_wait().unwrap().is_none(),
        "the pipeline ended early"
    );
    let sent = Command::new("kill")
        .args([&format!("-{signal}"), &child.id().to_string()])
        .status()
        .unwrap();
    assert!(sent.success());
    let code = exit_code(&mut child, 30);
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    assert_eq!(code, Some(130), "{err}");
    assert!(err.contains("interrupted"), "{err}");
    assert_eq!(entries(&dir), Vec::<String>::new(), "left behind");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_long_explicit_solve_is_announced_and_ctrl_c_stops_it() {
    let dir = temp_dir("interrupt-empc");
    let mut child = Command::new(env!("CARGO_BIN_EXE_kestrel"))
        .args([
            "closed-loop",
            "--controller",
            "empc",
            "--size",
            "larger",
            "--out",
            "trace.csv",
        ])
        .current_dir(&dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The announcement comes before the solve starts (lines read on a
    // thread, so a missing one fails the test rather than waiting for the
    // 14-minute solve).
    let stderr = BufReader::new(child.stderr.take().unwrap());
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in stderr.lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let mut seen = String::new();
    while !seen.contains("note: explicit MPC") {
        match rx.recv_timeout(Duration::from_secs(120)) {
            Ok(line) => seen.push_str(&(line + "\n")),
            Err(_) => {
                let _ = child.kill();
                let _ = child.wait();
                panic!("no announcement of the long solve: {seen}");
            }
        }
    }
    assert!(
        seen.contains("about 70 s") && seen.contains("--controller fgm"),
        "{seen}"
    );
    std::thread::sleep(Duration::from_millis(1000));
    assert!(child.try_wait().unwrap().is_none(), "the solve ended early");
    interrupt(child.id());
    let code = exit_code(&mut child, 30);
    assert_eq!(code, Some(130));
    assert_eq!(entries(&dir), Vec::<String>::new(), "left behind");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn progress_is_shown_on_a_terminal_and_silent_in_a_pipe() {
    let dir = temp_dir("progress");
    let out = dir.join("hover.csv");
    let args = [
        "simulate",
        "--experiment",
        "hover",
        "--seconds",
        "100",
        "--out",
        out.to_str().unwrap(),
        // The second run replaces the first one's file.
        "--force",
    ];
    // Standard error a pipe (as in CI): the summary only, no spinner.
    let (ok, _, err) = common::kestrel(&args);
    assert!(ok, "{err}");
    assert!(
        !err.contains("flying experiment") && !err.contains('\r'),
        "{err:?}"
    );
    // On a terminal (a pseudo-terminal from util-linux's `script`, where
    // installed): the stage and its elapsed time.
    let line = format!("{} {}", env!("CARGO_BIN_EXE_kestrel"), args.join(" "));
    if let Ok(o) = Command::new("script")
        .args(["-qec", &line, "/dev/null"])
        .stdin(Stdio::null())
        .output()
    {
        let shown = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "{shown}");
        assert!(
            shown.contains("flying experiment hover") && shown.contains("[00:00:0"),
            "{shown:?}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
