//! SIGTERM and SIGINT as a stop request that the render loop checks between passes.
//!
//! The first signal sets a flag: the current pass finishes (passes last about
//! `render::PASS_SECONDS`), the image is written with the spp actually rendered, and
//! plume exits with code 5. A second signal exits at once with code 5; the atomic writes
//! leave no partial file, and the rerun continues from the last image written. Farm
//! schedulers send SIGTERM before SIGKILL (Slurm: `KillWait`, 30 s by default).

use std::sync::Once;

use signal_hook::consts::{SIGINT, SIGTERM};

pub use plume_core::stop::stop_requested;

static INSTALLED: Once = Once::new();

/// Install the handlers (once per process; later calls do nothing). They set the stop
/// flags of [`plume_core::stop`]. For the application to call: the second signal ends
/// the process.
///
/// # Errors
/// The OS error if a handler cannot be installed.
pub fn install() -> std::io::Result<()> {
    let mut result = Ok(());
    INSTALLED.call_once(|| {
        let flags = plume_core::stop::flags();
        for (signal, flag) in [(SIGTERM, &flags.term), (SIGINT, &flags.int)] {
            // Registered first, so it sees the flag as the previous signal left it: the
            // second signal exits immediately
            let registered = signal_hook::flag::register_conditional_shutdown(
                signal,
                plume_core::error::exit::INTERRUPTED,
                std::sync::Arc::clone(flag),
            )
            .and_then(|_| signal_hook::flag::register(signal, std::sync::Arc::clone(flag)));
            if let Err(e) = registered {
                result = Err(e);
                return;
            }
        }
    });
    result
}
