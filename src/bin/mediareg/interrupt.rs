//! Ctrl-C during `render`: the first asks the render to stop and write what it has.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, LazyLock};

use anyhow::{Context, Result};

/// Set by the first Ctrl-C during `render`: the render stops after dropping the pass
/// under way, and the image of the passes completed is written.
pub static INTERRUPT: LazyLock<Arc<AtomicBool>> = LazyLock::new(Arc::default);

/// The conventional exit status of a process ended by SIGINT (128 + 2).
pub const EXIT_INTERRUPTED: u8 = 130;

/// The first Ctrl-C asks the render to stop and write what it has; a second one quits
/// at once (atomic writes leave no partial file either way).
pub fn install_handler() -> Result<()> {
    ctrlc::set_handler(|| {
        if INTERRUPT.swap(true, Ordering::SeqCst) {
            eprintln!("\ninterrupted again: quitting without writing");
            std::process::exit(EXIT_INTERRUPTED as i32);
        }
        eprintln!(
            "\ninterrupted: writing the image rendered so far (Ctrl-C again to quit at once)"
        );
    })
    .context("cannot install the Ctrl-C handler")
}
