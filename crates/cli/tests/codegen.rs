//! End-to-end test of `kestrel codegen` on a copy of the workspace's inputs
//! and generated files: `--check` passes on the committed files, fails on
//! a deliberately stale table (naming it, writing nothing), and `kestrel
//! codegen` rewrites exactly that file. Nothing is written into the
//! repository.

mod common;

use std::path::{Path, PathBuf};

/// The folders `kestrel codegen` reads its inputs from and writes its
/// files to, relative to the workspace root.
const FOLDERS: &[&str] = &[
    "models",
    "avr/firmware/src",
    "crates/empc/tests/generated",
    "crates/empc/tests/data",
    "crates/fgm/tests/data",
    "crates/tricopter/data",
    "crates/avr-rt/tests/data",
    // kestrel-ffi's sources and cbindgen.toml: the C header's inputs.
    "crates/ffi",
    "crates/ffi/src",
    "crates/ffi/src/tests",
    "crates/ffi/include",
];

/// kestrel-ffi's generated C header.
const HEADER: &str = "crates/ffi/include/kestrel.h";

/// The table made stale.
const TABLE: &str = "avr/firmware/src/generated.rs";

/// A fresh folder `<name>` in the test process's scratch folder ([`common::temp_dir`], emptied first).
fn temp_dir(name: &str) -> PathBuf {
    let d = common::temp_dir(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Runs `kestrel codegen` with `args` in `dir`: success, stdout, stderr.
fn codegen(dir: &Path, args: &[&str]) -> (bool, String, String) {
    let args: Vec<&str> = std::iter::once("codegen")
        .chain(args.iter().copied())
        .collect();
    common::kestrel_in(dir, &args)
}

fn copy_folder(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        if e.file_type().unwrap().is_file() {
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
    }
}

/// Every file under `dir` with its contents, sorted by path.
fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push((p.clone(), std::fs::read(&p).unwrap()));
            }
        }
    }
    out.sort();
    out
}

#[test]
fn check_fails_on_a_stale_table_and_codegen_rewrites_it() {
    let root = temp_dir("codegen");
    for f in FOLDERS {
        copy_folder(&repo().join(f), &root.join(f));
    }
    std::fs::write(root.join("Cargo.toml"), "[workspace]\nmembers = []\n").unwrap();
    let root_arg = root.display().to_string();
    let anywhere = std::env::temp_dir();

    // The committed files are what the generator produces.
    let (ok, out, err) = codegen(&anywhere, &["--check", "--root", &root_arg]);
    assert!(ok, "committed generated files are stale:\n{out}\n{err}");
    assert!(out.contains("up to date"), "{out}");

    // A deliberately stale table: --check names it and writes nothing.
    let table = root.join(TABLE);
    let fresh = std::fs::read(&table).unwrap();
    let mut stale = fresh.clone();
    stale.push(b'\n');
    std::fs::write(&table, &stale).unwrap();
    let before = snapshot(&root);
    let (ok, out, err) = codegen(&anywhere, &["--check", "--root", &root_arg]);
    assert!(!ok, "--check passed on a stale table:\n{out}");
    assert!(
        err.contains(&format!("{TABLE}: stale")),
        "the stale table is not named:\n{err}"
    );
    assert!(
        err.contains("1 of ") && err.contains("run `kestrel codegen`"),
        "{err}"
    );
    assert_eq!(snapshot(&root), before, "--check wrote something");

    // `kestrel codegen` rewrites that file alone, from a folder inside the
    // root (the default root is found from the current directory).
    let (ok, out, err) = codegen(&root.join("avr/firmware"), &[]);
    assert!(ok, "{out}\n{err}");
    assert!(out.contains(&format!("wrote {TABLE} (was stale)")), "{out}");
    assert_eq!(out.matches("wrote ").count(), 1, "{out}");
    assert_eq!(std::fs::read(&table).unwrap(), fresh);
    let after = snapshot(&root);
    assert_eq!(after.len(), before.len(), "files appeared or vanished");

    let (ok, out, err) = codegen(&anywhere, &["--check", "--root", &root_arg]);
    assert!(ok, "still stale after `kestrel codegen`:\n{out}\n{err}");

    // A C header that no longer matches the sources (a function added to
    // kestrel-ffi) is stale too.
    let lib = root.join("crates/ffi/src/lib.rs");
    let mut src = std::fs::read_to_string(&lib).unwrap();
    src.push_str(
        "\n/// New.\n#[unsafe(no_mangle)]\npub extern \"C\" fn kestrel_new() -> u8 {\n    0\n}\n",
    );
    std::fs::write(&lib, src).unwrap();
    let (ok, _, err) = codegen(&anywhere, &["--check", "--root", &root_arg]);
    assert!(!ok && err.contains(&format!("{HEADER}: stale")), "{err}");
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn a_missing_input_is_an_error_naming_it() {
    let root = temp_dir("codegen-empty");
    std::fs::create_dir_all(root.join("avr/firmware")).unwrap();
    std::fs::write(root.join("Cargo.toml"), "[workspace]\n").unwrap();
    let (ok, _, err) = codegen(&root, &["--check"]);
    assert!(!ok);
    assert!(err.contains("models/tricopter-blackbox-5.json"), "{err}");
    assert_eq!(snapshot(&root).len(), 1, "wrote something");
    std::fs::remove_dir_all(&root).unwrap();
}

/// `--root` must name a workspace root: a folder that only holds the
/// design model (no `[workspace]`, no `avr/firmware`) is refused before
/// anything is generated into it.
#[test]
fn a_root_that_is_no_workspace_is_refused() {
    let root = temp_dir("codegen-no-workspace");
    copy_folder(&repo().join("models"), &root.join("models"));
    let before = snapshot(&root);
    let root_arg = root.display().to_string();
    let (ok, _, err) = codegen(&std::env::temp_dir(), &["--root", &root_arg]);
    assert!(!ok);
    assert!(err.contains("not a workspace root"), "{err}");
    assert_eq!(snapshot(&root), before, "wrote something");
    std::fs::remove_dir_all(&root).unwrap();
}
