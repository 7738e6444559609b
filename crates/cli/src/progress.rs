//! Progress on a terminal: what a command is doing and for how long, on
//! standard error, redrawn in place; nothing at all when standard error
//! is not a terminal (a pipe, a file, the tests, CI).

use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::Duration;

/// The bar on screen, cleared by the Ctrl-C handler.
static CURRENT: Mutex<Option<indicatif::ProgressBar>> = Mutex::new(None);

/// Whether progress is shown: standard error is a terminal.
pub fn enabled() -> bool {
    std::io::stderr().is_terminal()
}

/// A spinner with the elapsed time and a message, shown while it lives
/// (hidden when [`enabled`] is false).
pub struct Spinner(indicatif::ProgressBar);

impl Spinner {
    /// Starts a spinner showing `message`.
    pub fn new(message: &str) -> Self {
        let bar = if enabled() {
            let pb = indicatif::ProgressBar::new_spinner();
            pb.set_style(
                indicatif::ProgressStyle::with_template("{spinner} [{elapsed_precise}] {msg}")
                    .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
            );
            pb.enable_steady_tick(Duration::from_millis(200));
            pb
        } else {
            indicatif::ProgressBar::hidden()
        };
        bar.set_message(message.to_string());
        show(&bar);
        Spinner(bar)
    }
}

impl Drop for Spinner {
    fn drop(&mut self) {
        self.0.finish_and_clear();
        if let Ok(mut c) = CURRENT.lock() {
            *c = None;
        }
    }
}

/// Makes `bar` the one [`clear`] clears.
pub fn show(bar: &indicatif::ProgressBar) {
    if let Ok(mut c) = CURRENT.lock() {
        *c = Some(bar.clone());
    }
}

/// Clears the bar on screen (before a message on an interrupt), and the
/// terminal's current line, where a library's own bar may be.
pub fn clear() {
    if let Ok(c) = CURRENT.try_lock()
        && let Some(bar) = c.as_ref()
    {
        bar.finish_and_clear();
    }
    if enabled() {
        eprint!("\r\x1b[2K");
    }
}
