//! Ctrl-C: an interrupted command exits with status 130 and leaves
//! nothing behind; so does one stopped by SIGTERM (`kill`, `timeout`) or
//! SIGHUP (a closed terminal), also with 130: the handler is not told
//! which signal came.
//!
//! Outputs are staged in temporary files ([`crate::io::Outputs`]) and a
//! report in a staging directory ([`crate::report::ReportDir`]); both are
//! removed when dropped, but SIGINT ends the process without running any
//! destructor, so without this module an interrupted command would leave
//! `.name.XXXX.tmp` files and `.report.partial-*` directories behind.
//!
//! Every such leftover is registered here while it exists. The handler
//! (the `ctrlc` crate with its `termination` feature, chosen over
//! signal-hook for its one call that installs a portable handler: it
//! waits for the signal on a thread of its own, so
//! the handler is ordinary code that may lock a mutex and remove files,
//! unlike a raw signal handler) removes what is registered and exits with
//! 130 (128 + SIGINT, what a shell reports for a process killed by Ctrl-C).
//! Creating a leftover and registering it happen under the registry's
//! lock, and so does putting outputs in place ([`with_registry`]): the
//! handler waits for a commit that has begun, so an interrupt leaves either
//! every output of the command or none of them.

use std::path::PathBuf;
use std::sync::{Mutex, MutexGuard, PoisonError};

/// Something an interrupted command must remove.
#[derive(Debug)]
pub enum Leftover {
    /// A temporary file.
    File(PathBuf),
    /// A staging directory and everything in it.
    Tree(PathBuf),
    /// Directories the command made, deepest first, each removed while empty.
    EmptyDirs(Vec<PathBuf>),
}

impl Leftover {
    fn remove(&self) {
        match self {
            Leftover::File(p) => {
                let _ = std::fs::remove_file(p);
            }
            Leftover::Tree(p) => {
                let _ = std::fs::remove_dir_all(p);
            }
            Leftover::EmptyDirs(dirs) => {
                for d in dirs {
                    if std::fs::remove_dir(d).is_err() {
                        break;
                    }
                }
            }
        }
    }
}

/// The leftovers that exist now, in the order they were made.
#[derive(Debug, Default)]
pub struct Registry {
    next: u64,
    entries: Vec<(u64, Leftover)>,
}

/// A registered leftover: dropped, it is forgotten by the registry (its
/// owner removes it, or has put it in place). Never drop an armed token
/// inside [`with_registry`]: [`Registry::release`] it there instead.
#[derive(Debug)]
pub struct Token(Option<u64>);

impl Registry {
    /// Registers `leftover` until the token is dropped or released.
    pub fn add(&mut self, leftover: Leftover) -> Token {
        let id = self.next;
        self.next += 1;
        self.entries.push((id, leftover));
        Token(Some(id))
    }

    /// Forgets the leftover of `token` (it is about to be put in place or removed).
    pub fn release(&mut self, token: &mut Token) {
        if let Some(id) = token.0.take() {
            self.entries.retain(|(k, _)| *k != id);
        }
    }
}

impl Drop for Token {
    fn drop(&mut self) {
        if self.0.is_some() {
            with_registry(|r| r.release(self));
        }
    }
}

static REGISTRY: Mutex<Registry> = Mutex::new(Registry {
    next: 0,
    entries: Vec::new(),
});

fn lock() -> MutexGuard<'static, Registry> {
    REGISTRY.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Runs `f` with the registry locked: a Ctrl-C meanwhile waits until `f`
/// returns. Create and register a leftover in one call, and put outputs
/// in place in one call.
pub fn with_registry<T>(f: impl FnOnce(&mut Registry) -> T) -> T {
    f(&mut lock())
}

/// Installs the Ctrl-C handler (once, at start). Should that fail (a
/// handler already installed), the command runs without it.
pub fn install() {
    let _ = ctrlc::set_handler(|| {
        let registry = lock();
        for (_, leftover) in registry.entries.iter().rev() {
            leftover.remove();
        }
        crate::progress::clear();
        eprintln!("interrupted: stopped; no unfinished output is left behind");
        std::process::exit(130);
    });
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Whether `path` is registered (other tests may register their own).
    pub(crate) fn registered(path: &std::path::Path) -> bool {
        with_registry(|r| {
            r.entries.iter().any(|(_, l)| match l {
                Leftover::File(p) | Leftover::Tree(p) => p == path,
                Leftover::EmptyDirs(d) => d.iter().any(|p| p == path),
            })
        })
    }

    #[test]
    fn leftovers_are_registered_until_released_or_dropped_and_removed_by_kind() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("x.tmp");
        let t = dir.path().join("staging");
        let made = dir.path().join("made");
        std::fs::write(&f, "x").unwrap();
        std::fs::create_dir_all(t.join("sub")).unwrap();
        std::fs::create_dir(&made).unwrap();
        let mut tf = with_registry(|r| r.add(Leftover::File(f.clone())));
        let tt = with_registry(|r| r.add(Leftover::Tree(t.clone())));
        assert!(registered(&f) && registered(&t));
        with_registry(|r| r.release(&mut tf));
        assert!(!registered(&f));
        drop(tt);
        assert!(!registered(&t));
        // What the Ctrl-C handler does with each kind.
        Leftover::File(f.clone()).remove();
        Leftover::Tree(t.clone()).remove();
        std::fs::write(made.join("keep"), "user's").unwrap();
        Leftover::EmptyDirs(vec![made.clone()]).remove();
        assert!(!f.exists() && !t.exists());
        assert!(made.join("keep").exists(), "a directory with files is kept");
    }
}
