//! A path's events, recorded when a sample is replayed with `--debug-pixel`.

/// Receives a path's events when a sample is replayed with `--debug-pixel`. The render
/// loop uses [`NoTrace`], which compiles to nothing.
pub trait Trace {
    /// Record one event; `message` is only called when tracing.
    fn event(&mut self, message: impl FnOnce() -> String);
}

/// Tracing off.
pub struct NoTrace;

impl Trace for NoTrace {
    #[inline(always)]
    fn event(&mut self, _message: impl FnOnce() -> String) {}
}

/// Tracing into a list of lines.
#[derive(Default)]
pub struct LineTrace(pub Vec<String>);

impl Trace for LineTrace {
    fn event(&mut self, message: impl FnOnce() -> String) {
        self.0.push(message());
    }
}
